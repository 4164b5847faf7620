//! `biped walk` links sim_bridge, so the `biped` binary (and this package's tests and
//! benches) need the rpath to the MuJoCo library that sim_bridge's build script gives its
//! own targets: see sim_bridge/build.rs. walk_eval, which links sim_bridge too, uses this
//! same script (`build = "../build.rs"`).

fn main() {
    const VAR: &str = "MUJOCO_DYNAMIC_LINK_DIR";
    println!("cargo::rerun-if-env-changed={VAR}");
    // sim_bridge's build script fails with the explanation when the folder is missing.
    if let Some(dir) = std::env::var_os(VAR) {
        println!(
            "cargo::rustc-link-arg=-Wl,-rpath,{}",
            std::path::Path::new(&dir).display()
        );
    }
}
