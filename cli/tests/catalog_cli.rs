//! Claim (issue 36 item 4): `mktree catalog create` describes local files
//! and URLs into a catalog, `catalog show` lists it, and `catalog query`
//! answers with each model's own answer, keys qualified by model, opening
//! only the models whose root box the region meets; a catalog that is not
//! one is refused in one line.

mod common;

use common::{mktree, serve, tanker1_in};
use serde_json::Value;

fn run(args: &[&str]) -> Value {
    let out = mktree().args(args).output().unwrap();
    assert!(out.status.success(), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).unwrap()
}

#[test]
fn a_catalog_of_a_file_and_a_url_answers_as_each_file() {
    let dir = tempfile::tempdir().unwrap();
    let (_, built) = tanker1_in(dir.path());
    let tiles = dir.path().join("tiles");
    let out =
        mktree().args(["export-3dtiles", built.to_str().unwrap(), tiles.to_str().unwrap()]).output().unwrap();
    assert!(out.status.success());
    std::fs::copy(&built, tiles.join("served.mkt")).unwrap();
    let (_server, port) = serve(dir.path());
    let catalog = dir.path().join("models.json");
    let url = format!("http://127.0.0.1:{port}/tiles/served.mkt");
    let created = run(&[
        "catalog",
        "create",
        catalog.to_str().unwrap(),
        built.to_str().unwrap(),
        &format!("remote={url}"),
        "--json",
    ]);
    let models = created["models"].as_array().unwrap();
    assert_eq!(models.len(), 2);
    assert_eq!(models[0]["model"], "t1");
    // A file beside the catalog is named relative to it.
    assert_eq!(models[0]["location"], "t1.mkt");
    assert_eq!(models[1]["location"], url.as_str());
    assert_eq!(models[0]["root_box"], models[1]["root_box"]);
    assert_eq!(run(&["catalog", "show", catalog.to_str().unwrap(), "--json"]), created);

    let query = |b: &str| run(&["catalog", "query", catalog.to_str().unwrap(), "--box", b, "--json"]);
    let near = query("0,0,0,4000,4000,4000");
    let local = run(&["query", built.to_str().unwrap(), "--box", "0,0,0,4000,4000,4000", "--json"]);
    let per_model = near["models"].as_array().unwrap();
    assert_eq!(per_model.len(), 2);
    assert_eq!(near["skipped"], 0);
    let keys = |model: &str| -> Vec<Value> {
        near["objects"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|o| o["model"] == model)
            .map(|o| o["key"].clone())
            .collect()
    };
    assert_eq!(Value::from(keys("t1")), local["keys"]);
    assert_eq!(Value::from(keys("remote")), local["keys"]);
    assert!(per_model[0]["transfer"].is_null());
    assert!(per_model[1]["transfer"]["requests"].as_u64().unwrap() >= 1);
    assert_eq!(per_model[0]["block_reads"], local["block_reads"]);

    let far = query("-9e9,-9e9,-9e9,-8e9,-8e9,-8e9");
    assert_eq!(far["skipped"], 2);
    assert_eq!(far["objects"].as_array().map(Vec::len), Some(0));

    std::fs::write(&catalog, b"{\"mktree_catalog\": 7}").unwrap();
    let out = mktree()
        .args(["catalog", "query", catalog.to_str().unwrap(), "--box", "0,0,0,1,1,1"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("version 7"), "{err}");
}
