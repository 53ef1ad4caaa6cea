//! Export to 3D Tiles 1.1: the tree as a tileset a web viewer
//! streams, refining a tile when its geometric error, projected to the
//! screen, passes its pixel threshold, the same test the view query makes.
//!
//! One tile per node, REPLACE refinement (hierarchical levels of detail):
//! an internal node shows its finest stored group bound b(S_n,k)
//! (format-spec/group.md; error: its largest cell's diagonal), or its box
//! b(S_n,1) where it stores none (error: the box's diagonal); a leaf shows
//! its group bound, or its objects' stand-ins (each object by its finest
//! stored bound below M or its box, whichever is closer), whichever is
//! within less (error: the group bound's, or the largest over the
//! objects), and has one child tile with the exact objects (error 0). A
//! tile's error is at least its children's, as 3D Tiles asks: where a child
//! stores a coarser bound than its parent (its finer one did not fit its
//! group block), the parent declares the child's error, an upper bound of
//! its own. Errors are in metres, as 3D Tiles has
//! them. Coordinates stay in millimetres relative to an anchor (the scene
//! box's lower corner), so f32 positions keep the file's precision; the root
//! tile's transform scales them to metres and moves them to the anchor.
//! glTF is y-up and 3D Tiles z-up: a position (x, y, z) is written to the
//! .glb as (x, z, -y), which a viewer's y-up to z-up turn brings back.
//! The .glb files are written with the `gltf` crate's JSON and GLB types.

use std::borrow::Cow;
use std::path::{Path, PathBuf};

use gltf::json;
use json::validation::Checked::Valid;
use json::validation::USize64;
use serde_json::{Value, json as jv};

use crate::bulk::Hierarchy;
use crate::db::{Piece, ReadTransaction, read_hierarchy};
use crate::geom::{Aabb, Point};
use crate::query::{Bound, QueryError, Shape};
use crate::render::level_colour;
use crate::scene::Mesh;
use crate::store::{ReadStats, StorageError};

/// Why an export failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TilesError {
    /// The file could not be read.
    #[error(transparent)]
    Storage(#[from] StorageError),
    /// A node or level the file does not hold, as the tree named it.
    #[error(transparent)]
    Query(#[from] QueryError),
    /// A file or folder of the export could not be written.
    #[error("{path}: {source}")]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// A tile's glTF (or the tileset's JSON) could not be built.
    #[error("tile {tile}: {detail}")]
    Gltf {
        /// The tile's name (`tileset` for the tileset's JSON).
        tile: String,
        /// What went wrong.
        detail: String,
    },
    /// The file holds no tree.
    #[error("the file holds no tree")]
    NoTree,
}

/// What an export wrote.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct TilesetReport {
    /// Tiles in the tileset.
    pub tiles: u64,
    /// .glb files written.
    pub glb_files: u64,
    /// Triangles written to the .glb files.
    pub triangles: u64,
    /// Bytes written: the .glb files and `tileset.json`.
    pub bytes: u64,
    /// The anchor, mm: the origin of the tiles' coordinates.
    pub anchor_mm: [f64; 3],
    /// Blocks read to gather the levels.
    pub reads: ReadStats,
}

/// Writes `txn`'s tree to `out` (created if missing): `tileset.json` and
/// one .glb per tile.
pub fn export_3d_tiles(txn: &ReadTransaction, out: &Path) -> Result<TilesetReport, TilesError> {
    let h = read_hierarchy(txn)?;
    let root = h.root().ok_or(TilesError::NoTree)?;
    std::fs::create_dir_all(out).map_err(|source| TilesError::Io { path: out.into(), source })?;
    let anchor = root.aabb.min;
    let mut w = Writer {
        txn,
        h: &h,
        out,
        anchor,
        m: txn.pager().lod_levels(),
        report: TilesetReport { anchor_mm: anchor.coords.into(), ..TilesetReport::default() },
    };
    let (mut tile, _) = w.tile(0)?;
    let to_m = 1e-3;
    tile["transform"] = jv!([
        to_m,
        0.0,
        0.0,
        0.0,
        0.0,
        to_m,
        0.0,
        0.0,
        0.0,
        0.0,
        to_m,
        0.0,
        anchor.x * to_m,
        anchor.y * to_m,
        anchor.z * to_m,
        1.0
    ]);
    let tileset = jv!({
        "asset": { "version": "1.1", "generator": "mktree" },
        "geometricError": tile["geometricError"].clone(),
        "root": tile,
    });
    let path = out.join("tileset.json");
    let text = serde_json::to_vec_pretty(&tileset)
        .map_err(|e| TilesError::Gltf { tile: "tileset".into(), detail: e.to_string() })?;
    w.report.bytes += text.len() as u64;
    std::fs::write(&path, text).map_err(|source| TilesError::Io { path, source })?;
    Ok(w.report)
}

struct Writer<'a> {
    txn: &'a ReadTransaction,
    h: &'a Hierarchy,
    out: &'a Path,
    anchor: Point,
    m: u8,
    report: TilesetReport,
}

/// A tile's meshes, each with its colour.
type Content = Vec<(Mesh, [u8; 3])>;

impl Writer<'_> {
    /// Node `id`'s tile and its box (node box, content and children, mm
    /// from the anchor).
    fn tile(&mut self, id: usize) -> Result<(Value, Aabb), TilesError> {
        let node = &self.h.nodes[id];
        let (content, error_mm, mut children) = match node.children() {
            Some(kids) => {
                let mut tiles = Vec::new();
                for k in kids {
                    tiles.push(self.tile(k.index())?);
                }
                match self.group(id as u32)? {
                    Some((content, error)) => (content, error, tiles),
                    None => {
                        let box_mesh = Shape::Box(node.aabb).mesh();
                        let colour = level_colour(Bound::NodeBox, 1, self.m);
                        (vec![(box_mesh, colour)], node.aabb.extent().norm(), tiles)
                    }
                }
            }
            None => {
                let (stand_ins, error) = match (self.stand_ins(id as u32)?, self.group(id as u32)?) {
                    ((_, e), Some((g, ge))) if ge <= e => (g, ge),
                    (objects, _) => objects,
                };
                let exact = self.exact(id as u32)?;
                let name = format!("n{id}-exact.glb");
                let written = self.write_glb(&name, &exact)?;
                let bounds = written.unwrap_or(Aabb::EMPTY).union(&self.local(&node.aabb));
                let child = tile_json(&bounds, 0.0, written.is_some().then_some(name.as_str()), Vec::new());
                self.report.tiles += 1;
                (stand_ins, error, vec![(child, bounds)])
            }
        };
        let error_mm = children
            .iter()
            .filter_map(|(t, _)| t["geometricError"].as_f64())
            .fold(error_mm, |e, child_m| e.max(child_m * 1e3));
        let name = format!("n{id}.glb");
        let own = self.write_glb(&name, &content)?;
        let start = own.unwrap_or(Aabb::EMPTY).union(&self.local(&node.aabb));
        let bounds = children.iter().fold(start, |b, (_, c)| b.union(c));
        let kids = children.drain(..).map(|(t, _)| t).collect();
        self.report.tiles += 1;
        let uri = own.is_some().then_some(name.as_str());
        Ok((tile_json(&bounds, error_mm * 1e-3, uri, kids), bounds))
    }

    /// Node `id`'s finest stored group bound as a mesh, and its error (mm).
    fn group(&mut self, id: u32) -> Result<Option<(Content, f64)>, TilesError> {
        // The record's flags say which levels are stored: a level that is
        // not would be gathered from the whole subtree.
        let (at, _) = self.txn.locate(id)?;
        let block = self.txn.block(
            at.block,
            crate::store::format::frame::BlockType::Node,
            at.checksum,
            &mut crate::db::Reads::new(None),
        )?;
        let finest = crate::db::view(&block, at.offset)?.group_levels().max();
        if let Some(k) = finest {
            let level = self.txn.fetch_level(id, k, false, &mut self.report.reads)?;
            if let Some(Piece::Group { voxels, level, .. }) = level.pieces.first() {
                let colour = level_colour(Bound::GroupBound, *level, self.m);
                return Ok(Some((vec![(voxels.boundary_mesh(), colour)], voxels.grid().max_cell_diagonal())));
            }
        }
        Ok(None)
    }

    /// `b` in the tiles' coordinates (mm from the anchor).
    fn local(&self, b: &Aabb) -> Aabb {
        Aabb::new(Point::from(b.min - self.anchor), Point::from(b.max - self.anchor))
    }

    /// A leaf's objects, each by its finest bound below M or its box,
    /// whichever is within less of it, and the largest of those errors (mm).
    fn stand_ins(&mut self, leaf: u32) -> Result<(Content, f64), TilesError> {
        let boxes = self.txn.fetch_level(leaf, 1, true, &mut self.report.reads)?;
        // An object stored as parts has a box per part: their union is its box.
        let mut whole: std::collections::BTreeMap<u32, Aabb> = Default::default();
        for p in &boxes.pieces {
            if let Piece::ObjectBoxes(b) = p {
                for (o, aabb) in b {
                    let w = whole.entry(o.0).or_insert(Aabb::EMPTY);
                    *w = w.union(aabb);
                }
            }
        }
        let mut best: std::collections::BTreeMap<u32, (f64, Shape)> =
            whole.into_iter().map(|(o, b)| (o, (b.extent().norm(), Shape::Box(b)))).collect();
        if self.m > 2 {
            let bounds = self.txn.fetch_level(leaf, self.m - 1, true, &mut self.report.reads)?;
            for p in &bounds.pieces {
                if let Piece::ObjectVoxels(v) = p {
                    for (o, v) in v {
                        let e = v.grid().max_cell_diagonal();
                        if best.get(&o.0).is_none_or(|b| e < b.0) {
                            best.insert(o.0, (e, Shape::Voxels(v.clone())));
                        }
                    }
                }
            }
        }
        let error = best.values().map(|b| b.0).fold(0.0, f64::max);
        // A voxel bound is the finest stored up to M - 1 (fetch_level does not say which).
        let k = |s: &Shape| if matches!(s, Shape::Voxels(_)) { self.m - 1 } else { 1 };
        let content = best
            .into_values()
            .map(|(_, s)| (s.mesh(), level_colour(Bound::ObjectBounds, k(&s), self.m)))
            .collect();
        Ok((content, error))
    }

    /// A leaf's exact objects.
    fn exact(&mut self, leaf: u32) -> Result<Content, TilesError> {
        let level = self.txn.fetch_level(leaf, self.m, true, &mut self.report.reads)?;
        let colour = level_colour(Bound::Exact, self.m, self.m);
        Ok(level
            .pieces
            .into_iter()
            .flat_map(|p| match p {
                Piece::Objects(o) => o.into_iter().map(|(_, m)| (m, colour)).collect(),
                _ => Vec::new(),
            })
            .collect())
    }

    /// Writes `content` as `name`; the box of its positions (mm from the
    /// anchor), `None` (and no file) when it has no triangle.
    fn write_glb(&mut self, name: &str, content: &Content) -> Result<Option<Aabb>, TilesError> {
        let mut glb = GlbBuilder::new();
        let mut bounds = Aabb::EMPTY;
        for (mesh, colour) in content {
            if mesh.triangle_count() == 0 {
                continue;
            }
            let local: Vec<Point> = mesh.vertices().map(|p| Point::from(p - self.anchor)).collect();
            bounds = local.iter().fold(bounds, |b, p| b.including(p));
            // z-up to glTF's y-up: (x, y, z) -> (x, z, -y).
            let positions: Vec<[f32; 3]> =
                local.iter().map(|p| [p.x as f32, p.z as f32, -p.y as f32]).collect();
            let indices: Vec<u32> = mesh.triangles().iter().flatten().copied().collect();
            glb.push_mesh(&positions, &indices, *colour);
            self.report.triangles += mesh.triangle_count() as u64;
        }
        let bytes = glb.into_bytes().map_err(|detail| TilesError::Gltf { tile: name.into(), detail })?;
        let Some(bytes) = bytes else { return Ok(None) };
        let path = self.out.join(name);
        self.report.bytes += bytes.len() as u64;
        self.report.glb_files += 1;
        std::fs::write(&path, bytes).map_err(|source| TilesError::Io { path, source })?;
        Ok(Some(bounds))
    }
}

/// A tile's .glb being built: its glTF JSON, its binary buffer, and its
/// scene's nodes, one per mesh.
struct GlbBuilder {
    root: json::Root,
    bin: Vec<u8>,
    nodes: Vec<json::Index<json::Node>>,
}

impl GlbBuilder {
    fn new() -> GlbBuilder {
        let root = json::Root {
            asset: json::Asset { generator: Some("mktree".into()), ..Default::default() },
            ..Default::default()
        };
        GlbBuilder { root, bin: Vec::new(), nodes: Vec::new() }
    }

    /// Adds a node of a mesh of the triangles `indices` over `positions`
    /// (in glTF's axes), in `colour`.
    fn push_mesh(&mut self, positions: &[[f32; 3]], indices: &[u32], colour: [u8; 3]) {
        let (lo, hi) = positions.iter().fold(([f32::MAX; 3], [f32::MIN; 3]), |(lo, hi), p| {
            (std::array::from_fn(|i| lo[i].min(p[i])), std::array::from_fn(|i| hi[i].max(p[i])))
        });
        let pos_view = self.view(bytemuck::cast_slice(positions), json::buffer::Target::ArrayBuffer);
        let idx_view = self.view(bytemuck::cast_slice(indices), json::buffer::Target::ElementArrayBuffer);
        let pos = self.root.push(accessor(
            pos_view,
            positions.len(),
            json::accessor::Type::Vec3,
            json::accessor::ComponentType::F32,
            Some(jv!(lo)),
            Some(jv!(hi)),
        ));
        let idx = self.root.push(accessor(
            idx_view,
            indices.len(),
            json::accessor::Type::Scalar,
            json::accessor::ComponentType::U32,
            None,
            None,
        ));
        let c = colour.map(|v| f32::from(v) / 255.0);
        let material = self.root.push(json::Material {
            double_sided: true,
            pbr_metallic_roughness: json::material::PbrMetallicRoughness {
                base_color_factor: json::material::PbrBaseColorFactor([c[0], c[1], c[2], 1.0]),
                metallic_factor: json::material::StrengthFactor(0.0),
                roughness_factor: json::material::StrengthFactor(1.0),
                ..Default::default()
            },
            ..Default::default()
        });
        let primitive = json::mesh::Primitive {
            attributes: [(Valid(json::mesh::Semantic::Positions), pos)].into_iter().collect(),
            extensions: None,
            extras: Default::default(),
            indices: Some(idx),
            material: Some(material),
            mode: Valid(json::mesh::Mode::Triangles),
            targets: None,
        };
        let m = self.root.push(json::Mesh {
            extensions: None,
            extras: Default::default(),
            name: None,
            primitives: vec![primitive],
            weights: None,
        });
        self.nodes.push(self.root.push(json::Node { mesh: Some(m), ..Default::default() }));
    }

    /// Appends `bytes` to the buffer, padded to 4 bytes, as a view for `target`.
    fn view(&mut self, bytes: &[u8], target: json::buffer::Target) -> json::Index<json::buffer::View> {
        let offset = self.bin.len();
        self.bin.extend_from_slice(bytes);
        self.bin.resize(self.bin.len().next_multiple_of(4), 0);
        self.root.push(json::buffer::View {
            buffer: json::Index::new(0),
            byte_length: USize64::from(bytes.len()),
            byte_offset: Some(USize64::from(offset)),
            byte_stride: None,
            extensions: None,
            extras: Default::default(),
            name: None,
            target: Some(Valid(target)),
        })
    }

    /// The .glb's bytes; `None` when it has no mesh.
    fn into_bytes(mut self) -> Result<Option<Vec<u8>>, String> {
        if self.nodes.is_empty() {
            return Ok(None);
        }
        self.root.push(json::Buffer {
            byte_length: USize64::from(self.bin.len()),
            extensions: None,
            extras: Default::default(),
            name: None,
            uri: None,
        });
        let scene = self.root.push(json::Scene {
            extensions: None,
            extras: Default::default(),
            name: None,
            nodes: self.nodes,
        });
        self.root.scene = Some(scene);
        let text = json::serialize::to_vec(&self.root).map_err(|e| e.to_string())?;
        let glb = gltf::binary::Glb {
            header: gltf::binary::Header { magic: *b"glTF", version: 2, length: 0 },
            json: Cow::Owned(text),
            bin: (!self.bin.is_empty()).then_some(Cow::Owned(self.bin)),
        };
        glb.to_vec().map(Some).map_err(|e| e.to_string())
    }
}

/// An accessor of `n` elements of type `ty` with components `component`,
/// read through `view`.
fn accessor(
    view: json::Index<json::buffer::View>,
    n: usize,
    ty: json::accessor::Type,
    component: json::accessor::ComponentType,
    min: Option<Value>,
    max: Option<Value>,
) -> json::Accessor {
    json::Accessor {
        buffer_view: Some(view),
        byte_offset: None,
        count: USize64::from(n),
        component_type: Valid(json::accessor::GenericComponentType(component)),
        extensions: None,
        extras: Default::default(),
        type_: Valid(ty),
        min,
        max,
        name: None,
        normalized: false,
        sparse: None,
    }
}

/// A tile of box `b` (mm from the anchor), error `error_m` metres, content
/// `uri`, children `kids`, REPLACE refinement.
fn tile_json(b: &Aabb, error_m: f64, uri: Option<&str>, kids: Vec<Value>) -> Value {
    let (c, e) = (b.center(), b.extent() / 2.0);
    let mut t = jv!({
        "boundingVolume": { "box": [c.x, c.y, c.z, e.x, 0.0, 0.0, 0.0, e.y, 0.0, 0.0, 0.0, e.z] },
        "geometricError": error_m,
        "refine": "REPLACE",
    });
    if let Some(uri) = uri {
        t["content"] = jv!({ "uri": uri });
    }
    if !kids.is_empty() {
        t["children"] = Value::Array(kids);
    }
    t
}
