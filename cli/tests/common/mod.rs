//! What the CLI tests share: the binary, and a generated scene built into a file.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;

pub fn mktree() -> Command {
    Command::new(env!("CARGO_BIN_EXE_mktree"))
}

/// tanker1 generated and built in `dir` with 4 KiB blocks: (t1.obj, t1.mkt).
pub fn tanker1_in(dir: &Path) -> (PathBuf, PathBuf) {
    let (obj, mkt) = (dir.join("t1.obj"), dir.join("t1.mkt"));
    for args in [
        vec!["gen", "tanker1", "-o", obj.to_str().unwrap()],
        vec!["build", obj.to_str().unwrap(), "-o", mkt.to_str().unwrap(), "--block-size", "4096"],
    ] {
        let out = mktree().args(&args).output().unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    }
    (obj, mkt)
}
