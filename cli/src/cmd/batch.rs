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

use std::io::{BufRead, BufReader, Write};
use std::path::Path;

use anyhow::{Context, Result};
use mktree::query::{Request, answer_request};
use serde_json::{Value, json};

pub fn run(file: &Path, queries: Option<&Path>, max_line: u64) -> Result<()> {
    let db = crate::input::open_to_read(file)?;
    let r = db.begin_read()?;
    let mut input: Box<dyn BufRead> = match queries {
        Some(p) => Box::new(BufReader::new(
            std::fs::File::open(p).with_context(|| format!("opening {}", p.display()))?,
        )),
        None => Box::new(std::io::stdin().lock()),
    };
    let mut out = std::io::stdout().lock();
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
        let answer = text
            .map_err(Clone::clone)
            .and_then(|t| serde_json::from_str::<Request>(t).map_err(|e| e.to_string()))
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
