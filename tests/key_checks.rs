//! One check per key wherever it appears: `rig.json` gets the physical checks of the
//! cell's sensor, each `[[trays]]` entry the checks of `[tray]` and `[items]`, a JSON file
//! holds one value, a placement names each parameter once; each refusal one line naming
//! the file (or flag) and the key.

use std::path::Path;

use crate::camplace_cmd::{assert_one_line_error, camplace, stderr};

/// A rendered scene's `rig.json` as JSON.
fn rendered_rig(d: &Path) -> serde_json::Value {
    if !d.join("r/rig.json").exists() {
        let o = camplace(d, &["render", "--out", "r"]);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    serde_json::from_slice(&std::fs::read(d.join("r/rig.json")).unwrap()).unwrap()
}

/// A change made to a `rig.json`.
type Edit = Box<dyn Fn(&mut serde_json::Value)>;

#[test]
fn rig_json_gets_the_sensors_physical_checks_in_every_command() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let rig = rendered_rig(d);
    let edits: Vec<(&str, Edit, &[&str])> = vec![
        ("tiny_fx", Box::new(|r| r["left"]["K"][0][0] = 1e-300.into()), &["left.K", "fx"]),
        ("far", Box::new(|r| r["right"]["T_world_camera"][0][3] = 1e200.into()), &["right.T_world_camera", "within"]),
        (
            "below",
            Box::new(|r| {
                for side in ["left", "right"] {
                    let z = r[side]["T_world_camera"][2][3].as_f64().unwrap();
                    r[side]["T_world_camera"][2][3] = (-z).into();
                }
            }),
            &["left.T_world_camera", "above the table"],
        ),
        ("folding", Box::new(|r| r["left"]["dist"][0] = (-3.0).into()), &["left.dist", "one-to-one"]),
    ];
    for (name, edit, keys) in &edits {
        let mut r = rig.clone();
        edit(&mut r);
        let file = format!("{name}.json");
        std::fs::write(d.join(&file), r.to_string()).unwrap();
        for args in [
            vec!["evaluate", "--rig", &file, "--scenarios", "1", "--out", "e"],
            vec!["placement", "--rig", &file],
            vec!["model", "--rig", &file, "--out", "m.model"],
        ] {
            let o = camplace(d, &args);
            let mut names = vec![file.as_str()];
            names.extend_from_slice(keys);
            assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &names);
        }
    }
    assert!(!d.join("e").exists() && !d.join("m.model").exists(), "nothing written for bad input");
    // Anything after the JSON value.
    let text = format!("{}\n{{}}", rig);
    std::fs::write(d.join("trailing.json"), text).unwrap();
    let o = camplace(d, &["placement", "--rig", "trailing.json"]);
    assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["trailing.json", "nothing after it"]);
}

#[test]
fn each_listed_tray_gets_the_checks_of_tray_and_items() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for (text, key) in [
        ("[[trays]]\nname = \"a\"\nroughness = 0.0\n", "trays[0].roughness"),
        ("[[trays]]\nname = \"a\"\nspecular = nan\n", "trays[0].specular"),
        ("[[trays]]\nname = \"a\"\n[trays.items]\nalbedo = 3.0\n", "trays[0].items.albedo"),
        ("[[trays]]\nname = \"all-trays\"\n", "trays[0].name"),
        ("[[trays]]\nname = \"report.html\"\n", "trays[0].name"),
        ("[[trays]]\nname = \"tolerance\"\n", "trays[0].name"),
    ] {
        std::fs::write(d.join("c.toml"), text).unwrap();
        let o = camplace(d, &["render", "--cell", "c.toml", "--out", "r"]);
        assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["c.toml", key]);
    }
}

#[test]
fn a_placement_with_a_parameter_twice_or_an_empty_field_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    for (p, key) in [("r=605,r=700", "placement.r"), ("r=605,,alpha=30", "placement"), ("r=605,", "placement")] {
        let o = camplace(dir.path(), &["render", "--placement", p, "--out", "r"]);
        assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["--placement", key]);
    }
}
