//! The scene format's JSON Schema (`porosph schema`, kept as
//! `docs/scene.schema.json` for editors): the file is current, an
//! independent validator (the `jsonschema` crate) accepts every scene in
//! `scenes/` and rejects unknown keys and out-of-range values, and every
//! key is described, which the error messages quote.

use porosph::scene::{schema, schema_text, Scene};
use serde_json::Value;
use std::path::PathBuf;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A TOML scene as the JSON value a schema validator sees.
fn as_json(toml_text: &str) -> Value {
    let v: toml::Value = toml::from_str(toml_text).expect("TOML");
    serde_json::to_value(v).expect("JSON")
}

fn validator() -> jsonschema::Validator {
    let text = std::fs::read_to_string(root().join("docs/scene.schema.json")).expect("read docs/scene.schema.json");
    let schema: Value = serde_json::from_str(&text).expect("the schema file is JSON");
    jsonschema::validator_for(&schema).expect("a valid JSON Schema")
}

#[test]
fn docs_scene_schema_json_is_current() {
    let file = std::fs::read_to_string(root().join("docs/scene.schema.json")).expect("read docs/scene.schema.json");
    assert!(
        file == schema_text(),
        "docs/scene.schema.json is out of date: run `cargo run --release -- schema > docs/scene.schema.json`"
    );
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_porosph")).arg("schema").output().expect("run porosph");
    assert!(out.status.success());
    assert_eq!(String::from_utf8(out.stdout).expect("UTF-8"), file, "`porosph schema` prints the file");
}

#[test]
fn every_scene_in_scenes_validates_against_the_schema() {
    let v = validator();
    let mut files: Vec<PathBuf> = std::fs::read_dir(root().join("scenes"))
        .expect("list scenes/")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    files.sort();
    assert!(files.len() >= 6, "{files:?}");
    for p in files {
        let text = std::fs::read_to_string(&p).expect("read scene");
        let errors: Vec<String> =
            v.iter_errors(&as_json(&text)).map(|e| format!("{} at {}", e, e.instance_path)).collect();
        assert!(errors.is_empty(), "{}: {errors:?}", p.display());
        Scene::from_file(&p).unwrap_or_else(|e| panic!("{e}"));
    }
}

#[test]
fn the_schema_rejects_unknown_keys_and_values_out_of_range() {
    let v = validator();
    let good = std::fs::read_to_string(root().join("scenes/dam_break.toml")).expect("read");
    assert!(v.is_valid(&as_json(&good)));
    let bad = [
        good.replacen("[simulation]", "[simulation]\ntime_step = 0.001", 1),
        good.replacen("[[fluid]]", "[[fluid]]\nveloctiy = [0.0, 0.0, 0.0]", 1),
        good.replacen("[simulation]", "[simulation]\ncfl_number = 1.5", 1),
        good.replacen("[simulation]", "[simulation]\ndrift_momentum = \"physcal\"", 1),
        good.replacen("[[fluid]]", "[[fluid]]\nmesh = { path = \"a.obj\", scal = 2.0 }", 1),
        format!("solver = \"iisph\"\n{good}"),
    ];
    for text in bad {
        assert!(!v.is_valid(&as_json(&text)), "accepted:\n{text}");
        assert!(Scene::from_toml_str(&text, "bad.toml").is_err());
    }
}

/// Every property of the schema has a description whose first line is
/// the noun phrase error messages use ("expected <it> (a number)").
#[test]
fn every_key_is_described() {
    fn walk(v: &Value, at: &str, missing: &mut Vec<String>) {
        if let Some(props) = v.get("properties").and_then(Value::as_object) {
            for (k, p) in props {
                let first = p.get("description").and_then(Value::as_str).and_then(|d| d.lines().next());
                match first {
                    Some(line) if !line.trim().is_empty() && !line.ends_with('.') => {}
                    _ => missing.push(format!("{at}.{k}")),
                }
                walk(p, &format!("{at}.{k}"), missing);
            }
        }
        if let Some(items) = v.get("items") {
            walk(items, &format!("{at}[]"), missing);
        }
        if let Some(defs) = v.get("definitions").and_then(Value::as_object) {
            for (k, d) in defs {
                walk(d, &format!("{at}/{k}"), missing);
            }
        }
    }
    let mut missing = Vec::new();
    walk(&schema(), "", &mut missing);
    assert!(missing.is_empty(), "keys without a one-line description: {missing:?}");
}
