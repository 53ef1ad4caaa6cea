//! The sets A and B of a clash test (docs/clash.md, "Selectors"): objects
//! chosen by their key, name or a field of their JSON payload, matched by a
//! glob (`*` any run of characters, `?` one character; a pattern without
//! either is an exact match, `PIPE*` a prefix). A set is the union of its
//! selectors.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Deserializer, Serialize, Serializer};

use super::ClashError;
use crate::scene::Key;

/// The longest selector text, bytes.
pub const MAX_SELECTOR: usize = 1024;

/// One selector: which objects it names.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Selector {
    /// Every object (`all`).
    All,
    /// Objects whose key matches (`key:GLOB`): an integer in decimal, a
    /// text key as is, other bytes in hex as `Key`'s `Display` shows them.
    Key(String),
    /// Objects whose name matches (`name:GLOB`).
    Name(String),
    /// Objects whose payload is a JSON object with `field` (a dotted path)
    /// matching: a string by its text, any other value by its JSON text
    /// (`payload.FIELD:GLOB`; `class:GLOB` is `payload.class:GLOB`, the
    /// IFC loader's class field).
    Payload {
        /// The dotted path of the field in the payload.
        field: String,
        /// The glob its value must match.
        pattern: String,
    },
}

/// What a selector sees of an object.
pub struct Candidate<'a> {
    /// Its key.
    pub key: &'a Key,
    /// Its name.
    pub name: &'a str,
    /// Its payload parsed as JSON (`None` when it is not JSON).
    pub payload: Option<&'a serde_json::Value>,
}

impl Selector {
    /// Whether the selector names the object.
    pub fn matches(&self, c: &Candidate) -> bool {
        match self {
            Selector::All => true,
            Selector::Key(p) => glob(p, &super::key_json::key_text(c.key)),
            Selector::Name(p) => glob(p, c.name),
            Selector::Payload { field, pattern } => {
                let Some(mut v) = c.payload else { return false };
                for part in field.split('.') {
                    match v.get(part) {
                        Some(x) => v = x,
                        None => return false,
                    }
                }
                match v {
                    serde_json::Value::String(s) => glob(pattern, s),
                    other => glob(pattern, &other.to_string()),
                }
            }
        }
    }

    /// Whether the selector reads payloads (so a run parses them).
    pub fn reads_payload(&self) -> bool {
        matches!(self, Selector::Payload { .. })
    }
}

impl FromStr for Selector {
    type Err = ClashError;

    fn from_str(s: &str) -> Result<Selector, ClashError> {
        let bad = |why: &str| ClashError::Selector { text: s.chars().take(80).collect(), why: why.into() };
        if s.len() > MAX_SELECTOR {
            return Err(bad("longer than 1,024 bytes"));
        }
        if s == "all" || s == "*" {
            return Ok(Selector::All);
        }
        let Some((kind, pattern)) = s.split_once(':') else {
            return Err(bad("expected all, key:GLOB, name:GLOB, class:GLOB or payload.FIELD:GLOB"));
        };
        let pattern = pattern.to_string();
        match kind {
            "key" => Ok(Selector::Key(pattern)),
            "name" => Ok(Selector::Name(pattern)),
            "class" => Ok(Selector::Payload { field: "class".into(), pattern }),
            _ => match kind.strip_prefix("payload.") {
                Some(field) if !field.is_empty() && field.split('.').all(|p| !p.is_empty()) => {
                    Ok(Selector::Payload { field: field.into(), pattern })
                }
                _ => Err(bad("expected all, key:GLOB, name:GLOB, class:GLOB or payload.FIELD:GLOB")),
            },
        }
    }
}

impl fmt::Display for Selector {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Selector::All => f.write_str("all"),
            Selector::Key(p) => write!(f, "key:{p}"),
            Selector::Name(p) => write!(f, "name:{p}"),
            Selector::Payload { field, pattern } => write!(f, "payload.{field}:{pattern}"),
        }
    }
}

impl Serialize for Selector {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl<'de> Deserialize<'de> for Selector {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Selector, D::Error> {
        let text = String::deserialize(d)?;
        text.parse().map_err(serde::de::Error::custom)
    }
}

/// Whether any selector of `set` names the object (an empty set names every object).
pub fn in_set(set: &[Selector], c: &Candidate) -> bool {
    set.is_empty() || set.iter().any(|s| s.matches(c))
}

/// `text` matches the glob `pattern`: `*` any run of characters (none
/// too), `?` one character, anything else itself. Linear in the text for
/// each `*` (the classic backtracking to the last star). Runs on the
/// bytes, a character at a time, without allocating: a run tests every
/// object against every selector (50,288 objects and 6 selectors spent 14%
/// of an IFC re-run collecting characters).
pub fn glob(pattern: &str, text: &str) -> bool {
    let (p, t) = (pattern.as_bytes(), text.as_bytes());
    let (mut i, mut j) = (0, 0);
    let mut star: Option<(usize, usize)> = None;
    while j < t.len() {
        // Both indices stay on character boundaries, so equal lead bytes
        // mean equal lengths, and equal bytes equal characters.
        let len = utf8_len(t[j]);
        if i < p.len() && p[i] == b'?' {
            i += 1;
            j += len;
        } else if i < p.len() && p[i] != b'*' && p[i..].starts_with(&t[j..j + len]) {
            i += len;
            j += len;
        } else if i < p.len() && p[i] == b'*' {
            star = Some((i, j));
            i += 1;
        } else if let Some((si, sj)) = star {
            let next = sj + utf8_len(t[sj]);
            i = si + 1;
            j = next;
            star = Some((si, next));
        } else {
            return false;
        }
    }
    p[i..].iter().all(|&c| c == b'*')
}

/// The length of the UTF-8 character whose first byte is `lead`.
fn utf8_len(lead: u8) -> usize {
    match lead {
        0..0xC0 => 1,
        0xC0..0xE0 => 2,
        0xE0..0xF0 => 3,
        _ => 4,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn globs_match_prefixes_wildcards_and_exact_text() {
        assert!(glob("PIPE*", "PIPE-101") && glob("PIPE*", "PIPE") && !glob("PIPE*", "XPIPE"));
        assert!(glob("*-1?1", "PIPE-101") && !glob("*-1?1", "PIPE-11"));
        assert!(glob("Ifc*Segment", "IfcPipeSegment") && !glob("Ifc*Segment", "IfcPipeSegments"));
        assert!(glob("abc", "abc") && !glob("abc", "abcd") && glob("*", "") && !glob("?", ""));
        assert!(glob("a*b*c", "axxbyyc") && !glob("a*b*c", "axxbyy"));
    }

    #[test]
    fn selectors_parse_show_and_match() {
        let key = Key::bytes("2O2Fr$t4X7Zf8NOew3FLOH").unwrap();
        let payload =
            serde_json::json!({"class": "IfcPipeSegment", "name": "Pipe 1", "dn": 100, "sys": {"id": "CW"}});
        let c = Candidate { key: &key, name: "Pipe 1", payload: Some(&payload) };
        for (text, hit) in [
            ("all", true),
            ("key:2O2F*", true),
            ("key:2O2G*", false),
            ("name:Pipe*", true),
            ("class:IfcPipe*", true),
            ("class:IfcWall", false),
            ("payload.dn:100", true),
            ("payload.sys.id:CW", true),
            ("payload.sys.id:HW", false),
            ("payload.missing:*", false),
        ] {
            let s: Selector = text.parse().unwrap();
            assert_eq!(s.matches(&c), hit, "{text}");
            let again: Selector = s.to_string().parse().unwrap();
            assert_eq!(again, s);
        }
        for bad in ["pipe", "colour:red", "payload.:x", "payload.a..b:x", &"k".repeat(2000)] {
            assert!(bad.parse::<Selector>().is_err(), "{bad}");
        }
    }

    proptest! {
        /// A prefix glob matches exactly the texts that start with the prefix;
        /// a literal pattern matches only itself.
        #[test]
        fn prefix_and_literal_globs(prefix in "[a-c]{0,4}", text in "[a-c]{0,6}") {
            prop_assert_eq!(glob(&format!("{prefix}*"), &text), text.starts_with(&prefix));
            prop_assert_eq!(glob(&prefix, &text), prefix == text);
            prop_assert_eq!(glob(&format!("*{prefix}*"), &text), text.contains(&prefix));
        }

        /// The byte-wise glob answers as a plain match over characters,
        /// with wildcards anywhere and characters of every UTF-8 length.
        #[test]
        fn globs_match_as_characters_do(pattern in "[aé€𝄞*?]{0,6}", text in "[aé€𝄞]{0,8}") {
            prop_assert_eq!(glob(&pattern, &text), by_chars(&pattern.chars().collect::<Vec<_>>(), &text.chars().collect::<Vec<_>>()));
        }
    }

    /// The glob's meaning, by recursion over characters.
    fn by_chars(p: &[char], t: &[char]) -> bool {
        match p.split_first() {
            None => t.is_empty(),
            Some(('*', rest)) => (0..=t.len()).any(|k| by_chars(rest, &t[k..])),
            Some((&c, rest)) => {
                t.split_first().is_some_and(|(&x, tail)| (c == '?' || c == x) && by_chars(rest, tail))
            }
        }
    }
}
