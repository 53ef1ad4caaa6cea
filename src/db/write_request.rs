//! Changes as data: a [`WriteRequest`] (the write lines of `mktree batch`,
//! through serde) applied to a [`WriteTransaction`] by [`apply_write`], and
//! its [`WriteAnswer`]. The requests are the transaction's own changes by
//! key: insert, update, move (a placement change without the mesh) and
//! remove (format-spec/commit.md says what a commit of them writes).

use serde::{Deserialize, Serialize};

use super::WriteTransaction;
use crate::geom::{Point, Vector};
use crate::scene::{Key, KeyError, Mesh, Object};

/// A key as JSON: a non-negative integer is [`Key::Int`], a string the
/// bytes of its UTF-8 ([`Key::bytes`], at most [`Key::MAX_BYTES`]).
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
#[serde(untagged)]
pub enum JsonKey {
    /// An integer key.
    Int(u64),
    /// A byte key, given as text.
    Text(String),
}

impl JsonKey {
    /// The key it names.
    pub fn to_key(&self) -> Result<Key, KeyError> {
        match self {
            JsonKey::Int(k) => Ok(Key::Int(*k)),
            JsonKey::Text(t) => Key::bytes(t.as_bytes()).map_err(KeyError::from),
        }
    }
}

/// A new object's geometry and name, as JSON: world coordinates (mm) and
/// triangles as vertex indices.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JsonObject {
    /// The object's key.
    pub key: JsonKey,
    /// Its name; empty when absent.
    #[serde(default)]
    pub name: String,
    /// Its vertices, mm.
    pub vertices: Vec<[f64; 3]>,
    /// Its triangles, three indices into `vertices` each.
    pub triangles: Vec<[u32; 3]>,
}

impl JsonObject {
    fn to_object(&self) -> Result<Object, crate::Error> {
        let points: Vec<Point> = self.vertices.iter().map(|&[x, y, z]| Point::new(x, y, z)).collect();
        let mesh = Mesh::from_world(&points, self.triangles.clone())?;
        Ok(Object::new(self.name.clone(), mesh).with_key(self.key.to_key()?))
    }
}

/// One change, as a JSON object tagged by `"write"`, e.g.
/// `{"write": "move", "key": 42, "by": [100, 0, 0]}`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(tag = "write", rename_all = "snake_case", deny_unknown_fields)]
pub enum WriteRequest {
    /// Adds an object under a key no object has.
    Insert(JsonObject),
    /// Replaces the object of an existing key.
    Update(JsonObject),
    /// Moves the object of `key` by `by` (mm) without sending its mesh.
    Move {
        /// The object's key.
        key: JsonKey,
        /// The offset, mm.
        by: [f64; 3],
    },
    /// Removes the object of `key`.
    Remove {
        /// The object's key.
        key: JsonKey,
    },
}

/// What a [`WriteRequest`] did in its transaction (committed only with it).
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct WriteAnswer {
    /// The change: `insert`, `update`, `move` or `remove`.
    pub write: &'static str,
    /// The object's key.
    pub key: Key,
    /// Whether the key named an object before the change (an insert's is
    /// always false: an insert of a key in use is an error).
    pub found: bool,
}

/// Applies `request` to `w`. A move or removal of a key with no object
/// changes nothing and answers `found: false`; an insert of a key in use
/// and an update of a key with none are errors, as for
/// [`WriteTransaction::insert`] and [`WriteTransaction::update`].
pub fn apply_write(w: &mut WriteTransaction, request: &WriteRequest) -> Result<WriteAnswer, crate::Error> {
    Ok(match request {
        WriteRequest::Insert(o) => {
            let key = w.insert(o.to_object()?)?;
            WriteAnswer { write: "insert", key, found: false }
        }
        WriteRequest::Update(o) => {
            let object = o.to_object()?;
            let key = o.key.to_key()?;
            w.update(object)?;
            WriteAnswer { write: "update", key, found: true }
        }
        WriteRequest::Move { key, by } => {
            let key = key.to_key()?;
            let found = w.move_by(&key, Vector::new(by[0], by[1], by[2]))?;
            WriteAnswer { write: "move", key, found }
        }
        WriteRequest::Remove { key } => {
            let key = key.to_key()?;
            let found = w.remove(&key)?.is_some();
            WriteAnswer { write: "remove", key, found }
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn requests_parse_by_their_tag_and_keys_by_their_json_type() {
        let m: WriteRequest =
            serde_json::from_str(r#"{"write": "move", "key": 7, "by": [1, 2, 3]}"#).unwrap();
        assert_eq!(m, WriteRequest::Move { key: JsonKey::Int(7), by: [1.0, 2.0, 3.0] });
        let r: WriteRequest = serde_json::from_str(r#"{"write": "remove", "key": "pump-7"}"#).unwrap();
        assert_eq!(r, WriteRequest::Remove { key: JsonKey::Text("pump-7".into()) });
        assert_eq!(JsonKey::Text("pump-7".into()).to_key().unwrap(), Key::bytes("pump-7").unwrap());
        let i: WriteRequest = serde_json::from_str(
            r#"{"write": "insert", "key": 1, "vertices": [[0,0,0],[1,0,0],[0,1,0]], "triangles": [[0,1,2]]}"#,
        )
        .unwrap();
        assert!(matches!(i, WriteRequest::Insert(JsonObject { ref name, .. }) if name.is_empty()));
        for bad in [
            r#"{"write": "move", "key": 7}"#,
            r#"{"write": "teleport", "key": 7}"#,
            r#"{"write": "remove", "key": -1}"#,
            r#"{"write": "remove", "key": 7, "extra": 1}"#,
        ] {
            assert!(serde_json::from_str::<WriteRequest>(bad).is_err(), "{bad}");
        }
        let long = JsonKey::Text("x".repeat(Key::MAX_BYTES + 1));
        assert!(long.to_key().is_err());
    }

    #[test]
    fn a_mesh_that_is_not_one_is_a_mesh_error() {
        let o: JsonObject =
            serde_json::from_str(r#"{"key": 1, "vertices": [[0,0,0],[1,0,0]], "triangles": [[0,1,2]]}"#)
                .unwrap();
        assert!(matches!(o.to_object(), Err(crate::Error::Mesh(_))));
    }
}
