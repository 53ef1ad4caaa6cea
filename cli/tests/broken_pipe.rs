//! Claim: a reader that closes the pipe early (`mktree ... | head`) ends the
//! CLI quietly, by SIGPIPE as Unix tools end, never by a panic.
#![cfg(unix)]

use std::os::unix::process::ExitStatusExt;
use std::process::{Command, Stdio};

fn mktree() -> Command {
    Command::new(env!("CARGO_BIN_EXE_mktree"))
}

#[test]
fn a_closed_pipe_ends_the_cli_without_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("t1.obj");
    let out = mktree().args(["gen", "tanker1", "-o", obj.to_str().unwrap()]).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    // The reading end is closed before the child starts, so no schedule can
    // let its output through.
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    let out = mktree()
        .args(["dump", obj.to_str().unwrap(), "--json"])
        .stdout(writer)
        .stderr(Stdio::piped())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert_eq!(out.status.signal(), Some(13), "status {:?}, stderr {stderr}", out.status);
}
