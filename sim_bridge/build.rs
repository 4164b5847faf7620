//! Lets this crate's binaries, tests and examples find the MuJoCo shared library at run time.
//!
//! mujoco-rs links `libmujoco.so` from `MUJOCO_DYNAMIC_LINK_DIR` (set for every cargo command
//! by `.cargo/config.toml` to `<repo>/.venv/mujoco-lib`, which `scripts/setup-python-env`
//! fills from the PyPI wheel). The loader then looks for `libmujoco.so.3.17.0`: an rpath to
//! the same folder finds it without `LD_LIBRARY_PATH`. `rustc-link-arg` applies to this
//! package's own targets only: a binary in another package that links sim_bridge needs the
//! same line in its own build script.

use std::path::Path;

const VAR: &str = "MUJOCO_DYNAMIC_LINK_DIR";
const HINT: &str = "run scripts/setup-python-env first (it installs MuJoCo from PyPI)";

fn main() {
    println!("cargo::rerun-if-env-changed={VAR}");
    let Some(dir) = std::env::var_os(VAR) else {
        fail(&format!(
            "{VAR} is not set (.cargo/config.toml sets it to <repo>/.venv/mujoco-lib); {HINT}"
        ));
    };
    let dir = Path::new(&dir);
    if !dir.join("libmujoco.so").exists() {
        fail(&format!(
            "{VAR} = {} holds no libmujoco.so; {HINT}",
            dir.display()
        ));
    }
    println!(
        "cargo::rerun-if-changed={}",
        dir.join("libmujoco.so").display()
    );
    println!("cargo::rustc-link-arg=-Wl,-rpath,{}", dir.display());
}

fn fail(message: &str) -> ! {
    eprintln!("sim_bridge: {message}");
    println!("cargo::warning=sim_bridge: {message}");
    std::process::exit(1);
}
