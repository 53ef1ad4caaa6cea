//! How a key is written in a clash's JSON (the CLI's lines, the status
//! store, format-spec/clash-store.md): an integer key as a JSON number, a
//! byte-string key that is plain text (UTF-8, no control character) as a
//! JSON string of that text (an IFC GlobalId as is, even one that begins
//! with `0x`), any other byte string as `{"hex": "..."}`. Every key reads
//! back as itself.

use serde::{Deserialize, Deserializer, Serializer};

use crate::scene::Key;

/// The text of a byte-string key that is plain text (UTF-8 with no control character).
pub fn plain_text(key: &Key) -> Option<&str> {
    match key {
        Key::Bytes(b) => std::str::from_utf8(b).ok().filter(|t| !t.chars().any(char::is_control)),
        Key::Int(_) => None,
    }
}

/// A key as a person reads it and selectors match it: an integer in
/// decimal, plain text as is, other bytes as `Key`'s `Display` shows them.
pub fn key_text(key: &Key) -> String {
    let mut text = String::new();
    write_key_text(&mut text, key);
    text
}

/// Appends [`key_text`] of `key` to `out`, with no string of its own (a
/// table of a million clashes writes two million keys).
pub fn write_key_text(out: &mut String, key: &Key) {
    use std::fmt::Write as _;
    match plain_text(key) {
        Some(t) => out.push_str(t),
        // Writing into a String cannot fail.
        None => {
            let _ = write!(out, "{key}");
        }
    }
}

fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02x}")).collect()
}

/// Writes `key` (serde's `with`).
pub fn serialize<S: Serializer>(key: &Key, s: S) -> Result<S::Ok, S::Error> {
    use serde::ser::SerializeMap;
    match (key, plain_text(key)) {
        (Key::Int(i), _) => s.serialize_u64(*i),
        (_, Some(t)) => s.serialize_str(t),
        (Key::Bytes(b), None) => {
            let mut m = s.serialize_map(Some(1))?;
            m.serialize_entry("hex", &hex(b))?;
            m.end()
        }
    }
}

/// Reads a key written by [`serialize`].
pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Key, D::Error> {
    #[derive(Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Hex {
        hex: String,
    }
    #[derive(Deserialize)]
    #[serde(untagged)]
    enum Form {
        Int(u64),
        Text(String),
        Hex(Hex),
    }
    let bytes = match Form::deserialize(d)? {
        Form::Int(i) => return Ok(Key::Int(i)),
        Form::Text(t) => t.into_bytes(),
        Form::Hex(Hex { hex }) => {
            if hex.len() % 2 != 0 || !hex.bytes().all(|b| b.is_ascii_hexdigit()) {
                return Err(serde::de::Error::custom("a key's hex is an even number of hex digits"));
            }
            (0..hex.len())
                .step_by(2)
                .map(|i| u8::from_str_radix(&hex[i..i + 2], 16))
                .collect::<Result<Vec<u8>, _>>()
                .map_err(serde::de::Error::custom)?
        }
    };
    Key::bytes(bytes).map_err(serde::de::Error::custom)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[derive(serde::Serialize, serde::Deserialize, PartialEq, Debug)]
    struct K(#[serde(with = "super")] Key);

    proptest! {
        /// Every key reads back as itself: integers, texts (digits alone and
        /// "0x..." among them) and bytes that are not text.
        #[test]
        fn every_key_reads_back(i in any::<u64>(), bytes in prop::collection::vec(any::<u8>(), 0..40), digits in "[0-9]{1,5}") {
            for key in [Key::Int(i), Key::bytes(bytes.clone()).unwrap(), Key::bytes(digits.clone()).unwrap(),
                        Key::bytes(format!("0x{digits}")).unwrap(), Key::bytes("0xkMi1RAz3LA$Z0EgcwT0").unwrap()] {
                let text = serde_json::to_string(&K(key.clone())).unwrap();
                let back: K = serde_json::from_str(&text).unwrap();
                prop_assert_eq!(back.0, key);
            }
        }
    }
}

#[test]
fn a_global_id_that_begins_with_0x_is_written_as_is() {
    let k = Key::bytes("0xkMi1RAz3LA$Z0EgcwT0").unwrap();
    assert_eq!(key_text(&k), "0xkMi1RAz3LA$Z0EgcwT0");
    #[derive(serde::Serialize)]
    struct K(#[serde(with = "self")] Key);
    assert_eq!(serde_json::to_string(&K(k)).unwrap(), "\"0xkMi1RAz3LA$Z0EgcwT0\"");
    assert_eq!(serde_json::to_string(&K(Key::bytes(vec![0xff, 1]).unwrap())).unwrap(), r#"{"hex":"ff01"}"#);
}
