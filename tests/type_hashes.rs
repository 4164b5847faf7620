//! Our RIHS01 type hashes against the ones rosidl computed when the ROS 2 message packages
//! were built: the PyPI wheels install `share/<pkg>/msg/<Name>.json` with a `type_hashes`
//! list (and scripts/setup-python-env builds our biped_msgs the same way).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::{Path, PathBuf};

use biped_msgs::type_description::{TypeLibrary, known_types, rihs01};

const WORKSPACE: &str = env!("CARGO_MANIFEST_DIR");

/// `<venv>/share`: beside the interpreter scripts/setup-python-env prints.
fn venv_share() -> PathBuf {
    let python = std::env::var_os("BIPED_PYTHON")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(WORKSPACE).join(".venv/bin/biped-python"));
    let share = python
        .parent()
        .and_then(Path::parent)
        .unwrap()
        .join("share");
    assert!(
        share.join("std_msgs/msg/String.json").exists(),
        "{} has no std_msgs type descriptions: run scripts/setup-python-env",
        share.display()
    );
    share
}

#[test]
fn every_known_type_hashes_as_rosidl_hashed_it() {
    let share = venv_share();
    for known in known_types() {
        let (pkg, name) = known.type_name.split_once("/msg/").unwrap();
        let file = share.join(pkg).join("msg").join(format!("{name}.json"));
        let text =
            std::fs::read_to_string(&file).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
        let json: serde_json::Value = serde_json::from_str(&text).unwrap();
        let theirs = json["type_hashes"]
            .as_array()
            .unwrap()
            .iter()
            .find(|h| h["type_name"] == known.type_name)
            .and_then(|h| h["hash_string"].as_str())
            .unwrap_or_else(|| panic!("{} lists no hash for {}", file.display(), known.type_name));
        assert_eq!(
            rihs01(known.type_name).unwrap(),
            theirs,
            "{}",
            known.type_name
        );
    }
}

/// The same hashes from an independent implementation: rosbags' own RIHS01 over its Jazzy
/// type store (which carries tf2_msgs, whose rosidl JSON above is built from our copy of
/// TFMessage.msg, tests/ros_interfaces/tf2_msgs), with biped_msgs registered from
/// msgs/msg/*.msg.
#[test]
fn every_known_type_hashes_as_rosbags_hashes_it() {
    let share = venv_share();
    let python = share.parent().unwrap().join("bin/biped-python");
    let names: Vec<&str> = known_types().iter().map(|k| k.type_name).collect();
    let script = "import pathlib, sys\n\
        from rosbags.typesys import Stores, get_typestore, get_types_from_msg\n\
        ts = get_typestore(Stores.ROS2_JAZZY)\n\
        for f in sorted(pathlib.Path(sys.argv[1]).glob('*.msg')):\n    \
            ts.register(get_types_from_msg(f.read_text(), f'biped_msgs/msg/{f.stem}'))\n\
        for name in sys.argv[2:]:\n    print(name, ts.hash_rihs01(name))\n";
    let out = std::process::Command::new(&python)
        .arg("-c")
        .arg(script)
        .arg(Path::new(WORKSPACE).join("msgs/msg"))
        .args(&names)
        .output()
        .unwrap_or_else(|e| panic!("{}: {e}", python.display()));
    assert!(
        out.status.success(),
        "rosbags: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    let mut checked = 0;
    for line in text.lines() {
        let (name, theirs) = line.split_once(' ').unwrap();
        assert_eq!(rihs01(name).unwrap(), theirs, "{name}");
        checked += 1;
    }
    assert_eq!(checked, names.len(), "{text}");
}

/// Types outside our table, read from the `.msg` files the ROS packages installed
/// (`TypeLibrary::add_from_prefixes`, as `biped record` does for a type it does not know):
/// every message type of every package in the venv hashes as rosidl hashed it.
#[test]
fn every_installed_msg_file_hashes_as_rosidl_hashed_it() {
    let share = venv_share();
    let prefixes = vec![share.parent().unwrap().to_path_buf()];
    let mut checked = 0;
    let mut packages: Vec<_> = std::fs::read_dir(&share)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    packages.sort();
    for pkg_dir in packages {
        let Ok(entries) = std::fs::read_dir(pkg_dir.join("msg")) else {
            continue;
        };
        let pkg = pkg_dir.file_name().unwrap().to_str().unwrap().to_owned();
        for e in entries {
            let path = e.unwrap().path();
            if path.extension().is_none_or(|x| x != "msg") {
                continue;
            }
            let name = path.file_stem().unwrap().to_str().unwrap();
            let type_name = format!("{pkg}/msg/{name}");
            let Ok(json) = std::fs::read_to_string(path.with_extension("json")) else {
                continue;
            };
            let json: serde_json::Value = serde_json::from_str(&json).unwrap();
            let theirs = json["type_hashes"]
                .as_array()
                .unwrap()
                .iter()
                .find(|h| h["type_name"] == type_name.as_str())
                .and_then(|h| h["hash_string"].as_str())
                .unwrap()
                .to_owned();
            let mut lib = TypeLibrary::new();
            if lib.knows(&type_name) {
                continue; // ours: the tests above
            }
            lib.add_from_prefixes(&type_name, &prefixes)
                .unwrap_or_else(|e| panic!("{type_name}: {e}"));
            assert_eq!(lib.rihs01(&type_name).unwrap(), theirs, "{type_name}");
            // And through the definition a bag would store, read back by another library.
            let mut again = TypeLibrary::new();
            again
                .add_ros2msg(&type_name, &lib.ros2msg_definition(&type_name).unwrap())
                .unwrap();
            assert_eq!(again.rihs01(&type_name).unwrap(), theirs, "{type_name}");
            checked += 1;
        }
    }
    assert!(checked > 100, "only {checked} types checked");
}

#[test]
fn a_type_without_a_msg_file_is_refused_naming_where_we_looked() {
    let e = TypeLibrary::new()
        .add_from_prefixes("no_such_pkg/msg/Thing", &["/nowhere".into()])
        .unwrap_err();
    let text = e.to_string();
    assert!(
        text.contains("no_such_pkg/msg/Thing") && text.contains("/nowhere"),
        "{text}"
    );
}
