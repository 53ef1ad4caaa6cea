//! `mktree batch`: many queries through one open file. Each non-blank line
//! of the input is a JSON request (`mktree::query::Request`); each gets one
//! line of JSON: its answer with `"line"` (the input line number), or
//! `{"line": n, "error": "..."}` when the line is not a request or the
//! query fails. A bad line never stops the batch, and the exit status is 0
//! once every line is answered; it is 1 only when the file cannot be opened
//! or the input not read. Lines starting with `#` are comments. Every query
//! reads through the database's shared cache, so a block an earlier line
//! read is counted as a cache hit, not a read.

use std::io::{BufRead, BufReader, Write};
use std::path::Path;

use anyhow::{Context, Result};
use mktree::query::{Request, answer_request};
use serde_json::{Value, json};

pub fn run(file: &Path, queries: Option<&Path>) -> Result<()> {
    let db = crate::cmd::open_to_read(file)?;
    let r = db.begin_read()?;
    let input: Box<dyn BufRead> = match queries {
        Some(p) => Box::new(BufReader::new(
            std::fs::File::open(p).with_context(|| format!("opening {}", p.display()))?,
        )),
        None => Box::new(std::io::stdin().lock()),
    };
    let mut out = std::io::stdout().lock();
    for (i, line) in input.lines().enumerate() {
        let line = line.context("reading the requests")?;
        let text = line.trim();
        if text.is_empty() || text.starts_with('#') {
            continue;
        }
        let n = i + 1;
        let answer = serde_json::from_str::<Request>(text)
            .map_err(|e| e.to_string())
            .and_then(|q| answer_request(&r, &q, Some(r.cache())).map_err(|e| e.to_string()))
            .and_then(|a| serde_json::to_value(a).map_err(|e| e.to_string()));
        let value = match answer {
            Ok(Value::Object(mut a)) => {
                a.insert("line".into(), json!(n));
                Value::Object(a)
            }
            Ok(other) => json!({ "line": n, "answer": other }),
            Err(error) => json!({ "line": n, "error": error }),
        };
        writeln!(out, "{value}")?;
        out.flush()?;
    }
    Ok(())
}
