//! How a key is written in a clash's JSON (the CLI's lines, the status
//! store, format-spec/clash-store.md): an integer key as a JSON number, a
//! byte-string key as a JSON string, its text (an IFC GlobalId as is), or
//! `0x` and hex digits when the bytes are not plain text (as `Key`'s
//! `Display` shows them). Every key reads back as itself.

use serde::{Deserialize, Deserializer, Serializer};

use crate::scene::Key;

/// Writes `key` (serde's `with`).
pub fn serialize<S: Serializer>(key: &Key, s: S) -> Result<S::Ok, S::Error> {
    match key {
        Key::Int(i) => s.serialize_u64(*i),
        Key::Bytes(_) => s.collect_str(key),
    }
}

/// Reads a key written by [`serialize`].
pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Key, D::Error> {
    #[derive(Deserialize)]
    #[serde(untagged)]
    enum Form {
        Int(u64),
        Text(String),
    }
    match Form::deserialize(d)? {
        Form::Int(i) => Ok(Key::Int(i)),
        Form::Text(t) => from_text(&t).map_err(serde::de::Error::custom),
    }
}

/// The byte-string key a JSON string names.
pub fn from_text(t: &str) -> Result<Key, String> {
    let bytes = match t.strip_prefix("0x") {
        Some(hex) if hex.len() % 2 == 0 && hex.bytes().all(|b| b.is_ascii_hexdigit()) => (0..hex.len())
            .step_by(2)
            .map(|i| u8::from_str_radix(&hex[i..i + 2], 16).map_err(|e| e.to_string()))
            .collect::<Result<Vec<u8>, String>>()?,
        _ => t.as_bytes().to_vec(),
    };
    Key::bytes(bytes).map_err(|e| e.to_string())
}

/// A key as JSON (for callers building their own lines).
pub fn to_value(key: &Key) -> serde_json::Value {
    match key {
        Key::Int(i) => serde_json::Value::from(*i),
        Key::Bytes(_) => serde_json::Value::String(key.to_string()),
    }
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
                        Key::bytes(format!("0x{digits}")).unwrap(), Key::bytes("2O2Fr$t4X7Zf8NOew3FLOH").unwrap()] {
                let text = serde_json::to_string(&K(key.clone())).unwrap();
                let back: K = serde_json::from_str(&text).unwrap();
                prop_assert_eq!(back.0, key);
            }
        }
    }
}
