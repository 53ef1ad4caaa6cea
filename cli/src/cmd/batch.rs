//! `mktree batch`: many queries through one open file. Each non-blank line
//! of the input is a JSON request (`mktree::query::Request`); each gets one
//! line of JSON: its answer with `"line"` (the input line number), or
//! `{"line": n, "error": "..."}` when the line is not a request or the
//! query fails. A bad line never stops the batch: a line longer than
//! `--max-line` bytes (default 1 MiB: far above any request, a collide with
//! every field being under 300 bytes) or not UTF-8 gets an
//! error naming it too, and the over-long part is skipped, never held, so
//! endless input (`/dev/zero`) costs at most that many bytes. The error
//! comes as soon as the limit is passed, not when the line ends, so an
//! endless line is reported at once. The exit
//! status is 0 once every line is answered; it is 1 only when the file
//! cannot be opened or the input not read. Lines starting with `#` are
//! comments. Every query reads through the database's shared cache, so a
//! block an earlier line read is counted as a cache hit, not a read.
//!
//! A line with a `"write"` tag is a change (`mktree::db::WriteRequest`:
//! insert, update, move, remove by key). Changes go into one write
//! transaction that commits after every `--commit-every` of them (default
//! 1: each its own commit); the change's answer then holds `"committed"`
//! (the lines committed, the milliseconds since the first of them, and
//! the commit's `ChangeStats`), else `"pending": true`. A group still open
//! when the input ends commits then, answered by one last line without
//! `"line"`. Queries read the last commit, never a pending change. A
//! change that fails answers its error and leaves the group as it was; a
//! commit that fails answers its error, and the group's changes are lost.
//! A file this process may not write is opened to read, and its changes
//! answer that it is read-only.

use std::io::{BufRead, BufReader, Write};
use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};
use mktree::db::{Database, WriteRequest, WriteTransaction, WriterWait, apply_write};
use mktree::query::{Request, answer_request};
use mktree::{ReadTransaction, StorageError};
use serde_json::{Value, json};

pub fn run(file: &Path, queries: Option<&Path>, max_line: u64, commit_every: u64, wait: bool) -> Result<()> {
    let db = open(file)?;
    let mut input: Box<dyn BufRead> = match queries {
        Some(p) => Box::new(BufReader::new(
            std::fs::File::open(p).with_context(|| format!("opening {}", p.display()))?,
        )),
        None => Box::new(std::io::stdin().lock()),
    };
    let mut out = std::io::stdout().lock();
    let mut session = Session { db: &db, read: db.begin_read()?, write: None, wait, commit_every };
    let mut bytes = Vec::new();
    let mut skipping = false;
    for n in 1.. {
        if std::mem::take(&mut skipping) && !skip_line(&mut input).context("reading the requests")? {
            break;
        }
        let line = match read_line(&mut input, max_line, &mut bytes).context("reading the requests")? {
            Line::End => break,
            Line::TooLong => {
                skipping = true;
                Err(format!("line {n} is longer than {max_line} bytes (--max-line); skipped"))
            }
            Line::Read => std::str::from_utf8(&bytes).map_err(|e| {
                format!("line {n} is not UTF-8 (byte {} of the line); skipped", e.valid_up_to() + 1)
            }),
        };
        let text = line.as_ref().map(|t| t.trim());
        if let Ok(t) = text
            && (t.is_empty() || t.starts_with('#'))
        {
            continue;
        }
        let value = match text.map_err(Clone::clone).and_then(|t| session.answer(n, t)) {
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
    // The changes of a last, unfilled group commit when the input ends.
    if let Some(committed) = session.commit() {
        writeln!(out, "{}", committed.unwrap_or_else(|error| json!({ "error": error })))?;
    }
    Ok(())
}

/// The file, to change when this process may write it, else to read (its
/// write lines then answer with the error that it is read-only).
fn open(file: &Path) -> Result<Database> {
    match Database::open(file) {
        Ok(db) => {
            for w in db.warnings() {
                eprintln!("warning: {}: {w}", file.display());
            }
            Ok(db)
        }
        Err(StorageError::Open { error, .. })
            if matches!(
                error.kind(),
                std::io::ErrorKind::PermissionDenied | std::io::ErrorKind::ReadOnlyFilesystem
            ) =>
        {
            crate::input::open_to_read(file)
        }
        Err(e) => Err(crate::input::opening(e, file)),
    }
}

/// The batch's transactions: queries read the last commit; changes go
/// into a write transaction that commits every `commit_every` of them.
struct Session<'db> {
    db: &'db Database,
    read: ReadTransaction,
    /// The open write transaction, the input lines of its changes, and when it began.
    write: Option<(WriteTransaction<'db>, Vec<u64>, Instant)>,
    wait: bool,
    commit_every: u64,
}

impl Session<'_> {
    /// The answer to request line `n`.
    fn answer(&mut self, n: u64, text: &str) -> Result<Value, String> {
        let value: Value = serde_json::from_str(text).map_err(|e| e.to_string())?;
        if value.get("write").is_none() {
            let q: Request = serde_json::from_value(value).map_err(|e| e.to_string())?;
            let a = answer_request(&self.read, &q, Some(self.read.cache())).map_err(|e| e.to_string())?;
            return serde_json::to_value(a).map_err(|e| e.to_string());
        }
        let request: WriteRequest = serde_json::from_value(value).map_err(|e| e.to_string())?;
        if self.write.is_none() {
            let w = self
                .db
                .begin_write_with(if self.wait { WriterWait::Wait } else { WriterWait::Fail })
                .map_err(|e| e.to_string())?;
            self.write = Some((w, Vec::new(), Instant::now()));
        }
        let (w, lines, _) = self.write.as_mut().ok_or("no write transaction")?;
        let answer = apply_write(w, &request).map_err(|e| e.to_string())?;
        lines.push(n);
        let full = lines.len() as u64 >= self.commit_every;
        let mut value = serde_json::to_value(answer).map_err(|e| e.to_string())?;
        if let Value::Object(a) = &mut value {
            if full {
                let committed = self.commit().ok_or("no write transaction")??;
                a.insert("committed".into(), committed);
            } else {
                a.insert("pending".into(), json!(true));
            }
        }
        Ok(value)
    }

    /// Commits the open write transaction, if any; its answer: the lines
    /// it held, its time and what it wrote.
    fn commit(&mut self) -> Option<Result<Value, String>> {
        let (w, lines, began) = self.write.take()?;
        if lines.is_empty() {
            // Its only changes failed: nothing to commit, and the writer's lock goes.
            return None;
        }
        Some(
            w.commit_with_stats()
                .map_err(|e| format!("the commit of lines {lines:?} failed, and their changes with it: {e}"))
                .and_then(|stats| {
                    self.read = self.db.begin_read().map_err(|e| e.to_string())?;
                    Ok(json!({
                        "lines": lines,
                        "ms": began.elapsed().as_secs_f64() * 1e3,
                        "stats": stats,
                    }))
                }),
        )
    }
}

/// What [`read_line`] found.
#[derive(Debug, PartialEq, Eq)]
enum Line {
    /// A whole line, without its end, is in the buffer.
    Read,
    /// The line is longer than the limit: its first bytes are in the
    /// buffer, the rest is still to be skipped ([`skip_line`]).
    TooLong,
    /// The input ended (no bytes before it).
    End,
}

/// Reads one line (ending in `\n`, or at the input's end) into `line`,
/// holding at most `max` bytes of it: a longer one stops at the limit,
/// its rest left unread for [`skip_line`].
fn read_line(input: &mut dyn BufRead, max: u64, line: &mut Vec<u8>) -> std::io::Result<Line> {
    line.clear();
    let mut any = false;
    loop {
        let buf = match input.fill_buf() {
            Ok(b) => b,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e),
        };
        if buf.is_empty() {
            break;
        }
        any = true;
        let (chunk, done) = match buf.iter().position(|&b| b == b'\n') {
            Some(i) => (&buf[..i], Some(i + 1)),
            None => (buf, None),
        };
        let room = usize::try_from(max).unwrap_or(usize::MAX).saturating_sub(line.len());
        if chunk.len() > room {
            line.extend_from_slice(&chunk[..room]);
            input.consume(room);
            return Ok(Line::TooLong);
        }
        line.extend_from_slice(chunk);
        let used = done.unwrap_or(buf.len());
        input.consume(used);
        if done.is_some() {
            break;
        }
    }
    if line.last() == Some(&b'\r') {
        line.pop();
    }
    Ok(if any { Line::Read } else { Line::End })
}

/// Consumes the input up to and with the next `\n`, a buffer at a time:
/// false when the input ended first.
fn skip_line(input: &mut dyn BufRead) -> std::io::Result<bool> {
    loop {
        let buf = match input.fill_buf() {
            Ok(b) => b,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e),
        };
        if buf.is_empty() {
            return Ok(false);
        }
        match buf.iter().position(|&b| b == b'\n') {
            Some(i) => {
                input.consume(i + 1);
                return Ok(true);
            }
            None => {
                let n = buf.len();
                input.consume(n);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lines(input: &[u8], max: u64) -> Vec<(Line, Vec<u8>)> {
        let mut r = std::io::BufReader::with_capacity(4, input);
        let mut out = Vec::new();
        loop {
            let mut buf = Vec::new();
            match read_line(&mut r, max, &mut buf).unwrap() {
                Line::End => return out,
                Line::TooLong => {
                    out.push((Line::TooLong, buf));
                    if !skip_line(&mut r).unwrap() {
                        return out;
                    }
                }
                l => out.push((l, buf)),
            }
        }
    }

    #[test]
    fn lines_past_the_limit_are_skipped_and_the_next_read_whole() {
        let got = lines(b"short\nmuch too long a line\n\nlast", 8);
        assert_eq!(got[0], (Line::Read, b"short".to_vec()));
        assert_eq!(got[1].0, Line::TooLong);
        assert!(got[1].1.len() <= 8);
        assert_eq!(got[2], (Line::Read, Vec::new()));
        assert_eq!(got[3], (Line::Read, b"last".to_vec()));
        assert_eq!(got.len(), 4);
        assert_eq!(lines(b"exactly8\n", 8), [(Line::Read, b"exactly8".to_vec())]);
    }
}
