//! Keys: the application's own identity for an object (parry's "the caller
//! chooses the leaf data"), a 64-bit integer such as a database row id, or
//! up to 255 bytes such as an IFC GlobalId. Keys are unique in a tree, and
//! answers give them.

use std::cmp::Ordering;
use std::fmt;

/// An object's key. Integers order numerically and before byte strings,
/// which order lexicographically.
#[derive(Clone, PartialEq, Eq, Hash)]
pub enum Key {
    /// A 64-bit integer (a row id, an index).
    Int(u64),
    /// At most [`Key::MAX_BYTES`] bytes (a GUID, a path).
    Bytes(Box<[u8]>),
}

/// A key too long to store.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("a key of {len} bytes (at most {max})", max = Key::MAX_BYTES)]
pub struct KeyTooLong {
    /// The key's length, bytes.
    pub len: usize,
}

impl Key {
    /// The longest byte-string key.
    pub const MAX_BYTES: usize = 255;

    /// A byte-string key.
    pub fn bytes(bytes: impl Into<Vec<u8>>) -> Result<Key, KeyTooLong> {
        let bytes = bytes.into();
        if bytes.len() > Key::MAX_BYTES {
            return Err(KeyTooLong { len: bytes.len() });
        }
        Ok(Key::Bytes(bytes.into_boxed_slice()))
    }

    /// The key a person writes (`mktree get --key`, `remove --key`): an
    /// integer key when `text` is a canonical decimal below 2^64 (digits
    /// only, no sign, no leading zero but in "0"); the bytes `0x` and an
    /// even number of hex digits spell, as [`Display`](fmt::Display) writes
    /// a key that is not plain text (a name that is not UTF-8, say); else
    /// the byte-string key of its UTF-8 bytes. So `+5`, `05` and ` 5` are
    /// byte-string keys and never find key 5, and every key but a text of
    /// digits alone reads back from how it is shown.
    ///
    /// ```
    /// use mktree::scene::Key;
    /// assert_eq!(Key::parse("5")?, Key::Int(5));
    /// assert_eq!(Key::parse("+5")?, Key::bytes("+5")?);
    /// assert_eq!(Key::parse("05")?, Key::bytes("05")?);
    /// let latin1 = Key::bytes(b"caf\xe9".to_vec())?;
    /// assert_eq!(latin1.to_string(), "0x636166e9");
    /// assert_eq!(Key::parse("0x636166e9")?, latin1);
    /// # Ok::<(), mktree::scene::KeyTooLong>(())
    /// ```
    pub fn parse(text: &str) -> Result<Key, KeyTooLong> {
        let canonical = !text.is_empty()
            && text.bytes().all(|b| b.is_ascii_digit())
            && (text == "0" || !text.starts_with('0'));
        if let Ok(x) = text.parse::<u64>()
            && canonical
        {
            return Ok(Key::Int(x));
        }
        if let Some(hex) = text.strip_prefix("0x")
            && let Some(bytes) = decode_hex(hex)
        {
            return Key::bytes(bytes);
        }
        Key::bytes(text.as_bytes())
    }

    /// The integer, for an integer key.
    pub fn as_int(&self) -> Option<u64> {
        match self {
            Key::Int(x) => Some(*x),
            Key::Bytes(_) => None,
        }
    }

    /// Bytes of its stored form (format-spec/keys.md).
    pub fn encoded_len(&self) -> usize {
        match self {
            Key::Int(_) => 9,
            Key::Bytes(b) => 2 + b.len(),
        }
    }

    /// Appends its stored form: tag 0 and 8 big-endian bytes, or tag 1, a
    /// length byte and the bytes.
    pub(crate) fn encode(&self, out: &mut Vec<u8>) {
        match self {
            Key::Int(x) => {
                out.push(0);
                out.extend_from_slice(&x.to_be_bytes());
            }
            Key::Bytes(b) => {
                out.push(1);
                out.push(b.len() as u8);
                out.extend_from_slice(b);
            }
        }
    }

    /// Its stored form (format-spec/keys.md), for the fuzz targets' forgeries.
    #[cfg(feature = "internals")]
    pub fn stored(&self) -> Vec<u8> {
        let mut out = Vec::new();
        self.encode(&mut out);
        out
    }
}

/// A stored key in place.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(crate) enum KeyRef<'a> {
    Int(u64),
    Bytes(&'a [u8]),
}

impl<'a> KeyRef<'a> {
    /// The key at the start of `bytes` and its stored length.
    pub(crate) fn decode(bytes: &'a [u8]) -> Option<(KeyRef<'a>, usize)> {
        match bytes.first()? {
            0 => Some((KeyRef::Int(u64::from_be_bytes(bytes.get(1..9)?.try_into().ok()?)), 9)),
            1 => {
                let n = usize::from(*bytes.get(1)?);
                Some((KeyRef::Bytes(bytes.get(2..2 + n)?), 2 + n))
            }
            _ => None,
        }
    }

    pub(crate) fn to_key(self) -> Key {
        match self {
            KeyRef::Int(x) => Key::Int(x),
            KeyRef::Bytes(b) => Key::Bytes(b.into()),
        }
    }
}

impl Key {
    pub(crate) fn as_ref(&self) -> KeyRef<'_> {
        match self {
            Key::Int(x) => KeyRef::Int(*x),
            Key::Bytes(b) => KeyRef::Bytes(b),
        }
    }
}

impl Ord for KeyRef<'_> {
    fn cmp(&self, o: &Self) -> Ordering {
        match (self, o) {
            (KeyRef::Int(a), KeyRef::Int(b)) => a.cmp(b),
            (KeyRef::Int(_), KeyRef::Bytes(_)) => Ordering::Less,
            (KeyRef::Bytes(_), KeyRef::Int(_)) => Ordering::Greater,
            (KeyRef::Bytes(a), KeyRef::Bytes(b)) => a.cmp(b),
        }
    }
}

impl PartialOrd for KeyRef<'_> {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}

impl Ord for Key {
    fn cmp(&self, o: &Self) -> Ordering {
        self.as_ref().cmp(&o.as_ref())
    }
}

impl PartialOrd for Key {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}

impl From<u64> for Key {
    fn from(x: u64) -> Key {
        Key::Int(x)
    }
}

/// Integers as themselves; byte strings as text when they are UTF-8 with
/// no control characters, else as `0x` and hex digits.
/// The bytes an even number of hex digits spell (either case), if they are that.
fn decode_hex(hex: &str) -> Option<Vec<u8>> {
    if hex.is_empty() || !hex.len().is_multiple_of(2) {
        return None;
    }
    let digit = |c: u8| (c as char).to_digit(16);
    hex.as_bytes().chunks(2).map(|p| Some((digit(p[0])? * 16 + digit(p[1])?) as u8)).collect()
}

impl fmt::Display for Key {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Key::Int(x) => x.fmt(f),
            Key::Bytes(b) => match std::str::from_utf8(b) {
                Ok(s) if !s.chars().any(char::is_control) && !s.starts_with("0x") => f.write_str(s),
                _ => {
                    f.write_str("0x")?;
                    b.iter().try_for_each(|x| write!(f, "{x:02x}"))
                }
            },
        }
    }
}

impl fmt::Debug for Key {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Key::Int(x) => write!(f, "Key({x})"),
            Key::Bytes(_) => write!(f, "Key({:?})", self.to_string()),
        }
    }
}

/// JSON: an integer key as a number, a byte-string key as its display form.
impl serde::Serialize for Key {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            Key::Int(x) => s.serialize_u64(*x),
            Key::Bytes(_) => s.serialize_str(&self.to_string()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn key() -> impl Strategy<Value = Key> {
        prop_oneof![
            any::<u64>().prop_map(Key::Int),
            proptest::collection::vec(any::<u8>(), 0..=Key::MAX_BYTES)
                .prop_map(|b| Key::bytes(b).expect("short")),
        ]
    }

    proptest! {
        #[test]
        fn stored_keys_round_trip_and_keep_their_order(a in key(), b in key()) {
            let (mut x, mut y) = (Vec::new(), Vec::new());
            a.encode(&mut x);
            b.encode(&mut y);
            prop_assert_eq!(x.len(), a.encoded_len());
            x.push(7);
            let (back, n) = KeyRef::decode(&x).expect("decodes");
            prop_assert_eq!(&back.to_key(), &a);
            prop_assert_eq!(&x[n..], &[7u8][..]);
            let (ra, _) = KeyRef::decode(&x).expect("decodes");
            let (rb, _) = KeyRef::decode(&y).expect("decodes");
            prop_assert_eq!(ra.cmp(&rb), a.cmp(&b));
        }

        /// How a key is shown is how it is typed back (`get --key`), but
        /// for a text of digits alone, which reads as the integer.
        #[test]
        fn a_shown_key_parses_back_to_itself(k in key()) {
            let shown = k.to_string();
            let digits_text = matches!(k, Key::Bytes(_)) && matches!(Key::parse(&shown), Ok(Key::Int(_)));
            prop_assume!(!digits_text);
            prop_assert_eq!(Key::parse(&shown).unwrap(), k);
        }
    }

    #[test]
    fn typed_keys_are_integers_only_when_written_as_one() {
        assert_eq!(Key::parse("0"), Ok(Key::Int(0)));
        assert_eq!(Key::parse("18446744073709551615"), Ok(Key::Int(u64::MAX)));
        for text in ["+5", "05", " 5", "5 ", "-5", "18446744073709551616", "", "0x", "0x1", "0xzz"] {
            assert_eq!(Key::parse(text), Key::bytes(text), "{text:?}");
        }
        assert_eq!(Key::parse("0xFF00"), Key::bytes(vec![0xff, 0]));
    }

    #[test]
    fn integers_order_numerically_before_byte_strings() {
        let mut keys = vec![Key::bytes("a").unwrap(), Key::Int(300), Key::Int(2), Key::bytes("").unwrap()];
        keys.sort();
        assert_eq!(keys, vec![Key::Int(2), Key::Int(300), Key::bytes("").unwrap(), Key::bytes("a").unwrap()]);
    }

    #[test]
    fn long_and_truncated_keys_are_refused() {
        assert_eq!(Key::bytes(vec![0; 256]), Err(KeyTooLong { len: 256 }));
        assert!(KeyRef::decode(&[0, 1, 2]).is_none());
        assert!(KeyRef::decode(&[1, 5, b'a']).is_none());
        assert!(KeyRef::decode(&[2]).is_none());
    }

    #[test]
    fn keys_display_as_numbers_text_or_hex() {
        assert_eq!(Key::Int(42).to_string(), "42");
        assert_eq!(Key::bytes("2O2Fr$t4X7Zf8NOew3FLOH").unwrap().to_string(), "2O2Fr$t4X7Zf8NOew3FLOH");
        assert_eq!(Key::bytes(vec![0, 255]).unwrap().to_string(), "0x00ff");
    }
}
