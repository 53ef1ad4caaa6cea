//! `StagedScene`: a scene read once and kept on disk, for bulk loads of
//! scenes larger than memory. Per object it holds what the tree and the
//! layout need (box, record length, spill offset: 64 bytes, plus its name,
//! and its key and payload when it has them); meshes go to a spill file in
//! the geometry record format (format-spec/geometry.md) and are read back
//! one at a time, in leaf order, as the levels of detail are computed and
//! the geometry written. A staged scene loads the same tree, block for
//! block, as the [`Scene`](crate::Scene) of the same objects.

use std::borrow::Cow;
use std::path::Path;

use super::source::{ObjectSource, check_object};
use crate::bulk::BuildError;
use crate::geom::Aabb;
use crate::scene::import::{ImportOptions, load_each};
use crate::scene::{Key, KeyTooLong, Mesh, Object, ObjectId};
use crate::spill::SpillFile;
use crate::store::StorageError;
use crate::store::format::geometry;

/// Where an object's mesh lies in the spill file.
#[derive(Debug, Clone, Copy)]
struct Spilled {
    aabb: Aabb,
    offset: u64,
    len: u64,
}

/// Objects staged for a bulk load
/// ([`WriteTransaction::bulk_load_staged`](super::WriteTransaction::bulk_load_staged)).
/// The spill file lives in the folder given to [`StagedScene::create_in`]
/// and is removed when the staged scene is dropped (on Unix at once: only
/// the open handle keeps it, so a crash leaves nothing behind).
#[derive(Debug)]
pub struct StagedScene {
    spill: SpillFile,
    objects: Vec<Spilled>,
    names: String,
    name_ends: Vec<u64>,
    /// Objects with their own key, by id (ids ascend: objects are pushed in order).
    keys: Vec<(u32, Key)>,
    payloads: Vec<(u32, Box<[u8]>)>,
    triangles: u64,
}

impl StagedScene {
    /// An empty staged scene whose spill file goes in folder `dir` (best on
    /// the same disk as the database, with room for the scene's geometry).
    pub fn create_in(dir: &Path) -> Result<StagedScene, StorageError> {
        let spill = SpillFile::create_in(dir, "meshes")
            .map_err(|error| StorageError::Spill { path: dir.to_path_buf(), error })?;
        Ok(StagedScene {
            spill,
            objects: Vec::new(),
            names: String::new(),
            name_ends: Vec::new(),
            keys: Vec::new(),
            payloads: Vec::new(),
            triangles: 0,
        })
    }

    /// Adds `object`, which gets the next id. Refuses coordinates beyond
    /// the format's range and a payload over its limit, as a bulk load of
    /// a [`Scene`](crate::Scene) does (duplicate keys are found by the load).
    pub fn push(&mut self, object: Object) -> Result<ObjectId, crate::Error> {
        let id = ObjectId(u32::try_from(self.objects.len()).map_err(|_| BuildError::TooManyObjects {
            objects: self.objects.len(),
            max: u32::MAX as usize,
        })?);
        check_object(id, &object)?;
        let mut record = Vec::with_capacity(geometry::record_len(&object.mesh) as usize);
        geometry::encode_object(id, &object.mesh, &mut record);
        let offset = self.spill.append(&record).map_err(|error| self.spill_error(error))?;
        self.objects.push(Spilled { aabb: object.mesh.aabb(), offset, len: record.len() as u64 });
        self.triangles += object.mesh.triangle_count() as u64;
        self.names.push_str(&object.name);
        self.name_ends.push(self.names.len() as u64);
        if let Some(key) = object.key {
            self.keys.push((id.0, key));
        }
        if !object.payload.is_empty() {
            self.payloads.push((id.0, object.payload.into_boxed_slice()));
        }
        Ok(id)
    }

    /// Stages every object of the scene file at `path` (as
    /// [`load`](crate::scene::import::load) reads it; OBJ files are streamed),
    /// with the spill file in folder `spill_dir`. Returns the staged scene
    /// and its count of zero-area triangles (kept; callers warn about them).
    pub fn import(
        path: &Path,
        options: &ImportOptions,
        spill_dir: &Path,
    ) -> Result<(StagedScene, usize), crate::Error> {
        let mut staged = StagedScene::create_in(spill_dir)?;
        let mut refused = None;
        let degenerate = load_each(path, options, Some(spill_dir), &mut |object| {
            if refused.is_none() {
                refused = staged.push(object).err();
            }
        })?;
        match refused {
            Some(e) => Err(e),
            None => Ok((staged, degenerate)),
        }
    }

    /// Keys every object by its name (as bytes), as
    /// [`Scene::key_by_names`](crate::Scene::key_by_names) does; a bulk
    /// load then refuses names that are not unique.
    pub fn key_by_names(&mut self) -> Result<(), KeyTooLong> {
        self.keys = (0..self.objects.len() as u32)
            .map(|i| Ok((i, Key::bytes(self.name(ObjectId(i)).as_bytes())?)))
            .collect::<Result<_, KeyTooLong>>()?;
        Ok(())
    }

    /// Objects staged.
    pub fn len(&self) -> usize {
        self.objects.len()
    }

    /// True when no object is staged.
    pub fn is_empty(&self) -> bool {
        self.objects.is_empty()
    }

    /// Bytes of geometry in the spill file.
    pub fn spilled_bytes(&self) -> u64 {
        self.spill.len()
    }

    /// Gives back the spare room of the per-object tables, which grew by
    /// doubling: at 10^7 objects 430 MB of the objects' table alone, held
    /// through the whole load.
    pub(crate) fn shrink_to_fit(&mut self) {
        self.objects.shrink_to_fit();
        self.names.shrink_to_fit();
        self.name_ends.shrink_to_fit();
        self.keys.shrink_to_fit();
        self.payloads.shrink_to_fit();
    }

    /// Makes every pushed mesh readable.
    pub(crate) fn flush(&mut self) -> Result<(), StorageError> {
        self.spill.flush().map_err(|error| self.spill_error(error))
    }

    fn spill_error(&self, error: std::io::Error) -> StorageError {
        StorageError::Spill { path: self.spill.path().to_path_buf(), error }
    }

    /// Object `id`'s spilled record, appended to `out`.
    fn read_record(&self, id: ObjectId, out: &mut Vec<u8>) -> Result<(), StorageError> {
        let s =
            self.objects.get(id.index()).ok_or_else(|| StorageError::Invalid(format!("no object {id}")))?;
        let start = out.len();
        out.resize(start + s.len as usize, 0);
        self.spill.read_exact_at(&mut out[start..], s.offset).map_err(|error| self.spill_error(error))
    }
}

impl ObjectSource for StagedScene {
    fn len(&self) -> usize {
        self.objects.len()
    }

    fn aabb(&self, id: ObjectId) -> Aabb {
        self.objects.get(id.index()).map_or(Aabb::EMPTY, |s| s.aabb)
    }

    fn record_len(&self, id: ObjectId) -> u64 {
        self.objects.get(id.index()).map_or(0, |s| s.len)
    }

    fn key(&self, id: ObjectId) -> Key {
        match self.keys.binary_search_by_key(&id.0, |(i, _)| *i) {
            Ok(at) => self.keys[at].1.clone(),
            Err(_) => Key::Int(u64::from(id.0)),
        }
    }

    fn payload(&self, id: ObjectId) -> &[u8] {
        match self.payloads.binary_search_by_key(&id.0, |(i, _)| *i) {
            Ok(at) => &self.payloads[at].1,
            Err(_) => &[],
        }
    }

    fn name(&self, id: ObjectId) -> &str {
        let i = id.index();
        let start = if i == 0 { 0 } else { self.name_ends.get(i - 1).copied().unwrap_or(0) };
        let end = self.name_ends.get(i).copied().unwrap_or(start);
        self.names.get(start as usize..end as usize).unwrap_or("")
    }

    fn mesh(&self, id: ObjectId) -> Result<Cow<'_, Mesh>, StorageError> {
        let mut bytes = Vec::new();
        self.read_record(id, &mut bytes)?;
        let (_, mesh) = geometry::decode_object(id.0, &bytes)?;
        Ok(Cow::Owned(mesh))
    }

    fn triangle_count(&self) -> u64 {
        self.triangles
    }

    /// The spilled bytes are the record: copied, not decoded and encoded again.
    fn encode_record(&self, id: ObjectId, out: &mut Vec<u8>) -> Result<u64, StorageError> {
        let start = out.len();
        self.read_record(id, out)?;
        geometry::record_vertex_count(&out[start..])
            .ok_or_else(|| StorageError::Invalid(format!("object {id}'s spilled record is cut short")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Point;

    fn object(i: u32) -> Object {
        let x = f64::from(i) * 10.0;
        let v = [Point::new(x, 0.0, 0.0), Point::new(x + 1.5, 0.0, 0.0), Point::new(x, 2.25, 1.0)];
        Object::new(format!("o{i}"), Mesh::from_world(&v, vec![[0, 1, 2]]).expect("a triangle"))
    }

    #[test]
    fn meshes_names_keys_and_payloads_read_back_from_tables_shrunk_to_fit() {
        let dir = std::env::temp_dir();
        let mut staged = StagedScene::create_in(&dir).expect("spill file");
        for i in 0..50 {
            let mut o = object(i);
            if i % 7 == 0 {
                o = o.with_key(Key::Int(1000 + u64::from(i))).with_payload(vec![i as u8; 3]);
            }
            assert_eq!(staged.push(o).expect("pushed"), ObjectId(i));
        }
        staged.flush().expect("flushed");
        staged.shrink_to_fit();
        assert_eq!(staged.objects.capacity(), 50);
        assert_eq!(staged.name_ends.capacity(), 50);
        assert_eq!(staged.names.capacity(), staged.names.len());
        for i in 0..50 {
            let id = ObjectId(i);
            let o = object(i);
            assert_eq!(*staged.mesh(id).expect("read back"), o.mesh);
            assert_eq!(staged.aabb(id), o.mesh.aabb());
            assert_eq!(staged.name(id), o.name);
            let keyed = i % 7 == 0;
            assert_eq!(staged.key(id), Key::Int(if keyed { 1000 + u64::from(i) } else { u64::from(i) }));
            assert_eq!(staged.payload(id), if keyed { vec![i as u8; 3] } else { Vec::new() });
        }
        assert_eq!(staged.triangle_count(), 50);
    }

    #[test]
    fn out_of_range_objects_and_long_payloads_are_refused() {
        let mut staged = StagedScene::create_in(&std::env::temp_dir()).expect("spill file");
        let far = [Point::new(1e300, 0.0, 0.0), Point::new(1e300, 1.0, 0.0), Point::new(1e300, 0.0, 1.0)];
        let o = Object::new("far", Mesh::from_world(&far, vec![[0, 1, 2]]).expect("a triangle"));
        assert!(matches!(staged.push(o), Err(crate::Error::Build(_))));
        let long = object(0).with_payload(vec![0; Object::MAX_PAYLOAD + 1]);
        assert!(matches!(staged.push(long), Err(crate::Error::Key(_))));
        assert!(staged.is_empty());
    }
}
