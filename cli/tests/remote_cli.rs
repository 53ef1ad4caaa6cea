//! Claim (issue 36): the commands that read an .mkt file take a URL as well
//! as a path, and answer as from the local file: `query --json` (with what
//! the open and the query fetched, `"transfer"`), `check` and `stats`, here
//! over `mktree serve` (HTTP range requests on 127.0.0.1).

mod common;

use common::{mktree, serve, tanker1_in};
use serde_json::Value;

fn run(args: &[&str]) -> String {
    let out = mktree().args(args).output().unwrap();
    assert!(out.status.success(), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout).unwrap()
}

#[test]
fn read_commands_take_a_url_and_answer_as_the_local_file() {
    let dir = tempfile::tempdir().unwrap();
    let (_, built) = tanker1_in(dir.path());
    // `serve` serves a tileset's folder; the file is served beside it.
    let tiles = dir.path().join("tiles");
    run(&["export-3dtiles", built.to_str().unwrap(), tiles.to_str().unwrap()]);
    let mkt = tiles.join("t1.mkt");
    std::fs::copy(&built, &mkt).unwrap();
    let (_server, port) = serve(dir.path());
    let url = format!("http://127.0.0.1:{port}/tiles/t1.mkt");
    let local = mkt.to_str().unwrap();

    let query = |target: &str| -> Value {
        serde_json::from_str(&run(&["query", target, "--box", "0,0,0,4000,4000,4000", "--json"])).unwrap()
    };
    let (near, far) = (query(local), query(&url));
    assert_eq!(near["objects"], far["objects"]);
    assert!(!far["objects"].as_array().unwrap().is_empty());
    assert_eq!(near["block_reads"], far["block_reads"]);
    assert!(near.get("transfer").is_none());
    for step in ["open", "query"] {
        for count in ["requests", "bytes", "round_trips"] {
            assert!(far["transfer"][step][count].is_u64(), "{step} {count}: {far}");
        }
    }
    assert!(far["transfer"]["open"]["requests"].as_u64().unwrap() >= 1);

    let check: Value = serde_json::from_str(&run(&["check", &url, "--json"])).unwrap();
    assert_eq!(check["faults"].as_array().map(Vec::len), Some(0), "{check}");
    let (a, b): (Value, Value) = (
        serde_json::from_str(&run(&["stats", local, "--json"])).unwrap(),
        serde_json::from_str(&run(&["stats", &url, "--json"])).unwrap(),
    );
    assert_eq!(a["objects"], b["objects"]);
    assert_eq!(a["file"]["node_blocks"], b["file"]["node_blocks"]);

    // A URL that names nothing: one line, a non-zero exit.
    let out = mktree()
        .args(["query", &format!("http://127.0.0.1:{port}/tiles/none.mkt"), "--box", "0,0,0,1,1,1"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("none.mkt"), "{err}");
}
