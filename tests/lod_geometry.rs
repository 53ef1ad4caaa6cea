//! Claim: the voxel levels of detail (`mktree::lod`) are sound bounds and
//! sound witnesses, and their inline blobs are exact.
//!
//! - Conservative: every vertex and surface point lies in the voxelization
//!   of its meshes, filled (`of_meshes`) or of the surface only
//!   (`of_surfaces`), and the surface set is part of the filled one.
//! - A witness: every cell of a surface set, grown by the grid's tolerance,
//!   meets a triangle, so a query that holds such a cell (`holds_a_cell_in`)
//!   meets the surface; and `may_meet` never rules out a box that meets a
//!   triangle.
//! - Nesting: a surface or filled set lifts into the set of the next coarser
//!   lattice level and into a parent's grid; grids on one lattice nest.
//! - Boxes are disjoint and cover exactly the set cells; the boundary mesh
//!   encloses the solid outward; the measured error stays within the cell
//!   diagonal.
//! - Blobs (format-spec/lod.md) store no grid: it is the aligned grid, the
//!   whole lattice cells around the box the record holds. They round-trip
//!   over that box in every form, in the smallest form the spec names, with
//!   the spec's bytes and `encoded_len` their length; a reader refuses
//!   overlapping or stray boxes, unknown forms and misfit bitmaps, and
//!   decoding never panics on damaged or arbitrary bytes.

mod common;

use common::{box_mesh, triangle};
use mktree::geom::{Aabb, Point, Vector, intersects_triangle_box};
use mktree::lod::{
    Grid, Lattice, LodError, Voxels, aligned_grid, decode, encode, encoded_len, measured_error,
};
use mktree::scene::Mesh;
use proptest::prelude::*;

/// Random boxes (closed) and triangles (open) in a 100 mm cube.
fn arb_meshes() -> impl Strategy<Value = Vec<Mesh>> {
    let obj = (prop::array::uniform3(0.0f64..100.0), prop::array::uniform3(0.0f64..40.0), any::<bool>());
    prop::collection::vec(obj, 1..6).prop_map(|v| {
        v.into_iter()
            .map(|(lo, size, is_box)| {
                let hi = [lo[0] + size[0], lo[1] + size[1], lo[2] + size[2]];
                if is_box {
                    box_mesh(lo, hi)
                } else {
                    triangle(lo, [hi[0], lo[1], hi[2]], [lo[0], hi[1], hi[2]])
                }
            })
            .collect()
    })
}

fn arb_lattice() -> impl Strategy<Value = Lattice> {
    (prop::array::uniform3(-50.0f64..50.0), 1.0f64..8.0)
        .prop_map(|(o, cell)| Lattice { origin: Point::new(o[0], o[1], o[2]), cell })
}

fn bounds(meshes: &[Mesh]) -> Aabb {
    meshes.iter().fold(Aabb::EMPTY, |b, m| b.union(&m.aabb()))
}

fn triangles(meshes: &[Mesh]) -> Vec<[Point; 3]> {
    meshes.iter().flat_map(|m| m.triangle_points()).collect()
}

/// A point of triangle `t` at barycentric-ish coordinates (a, b).
fn on_triangle(t: &[Point; 3], a: f64, b: f64) -> Point {
    let (a, b) = if a + b > 1.0 { (1.0 - a, 1.0 - b) } else { (a, b) };
    t[0] + (t[1] - t[0]) * a + (t[2] - t[0]) * b
}

/// A stream of pseudo-random words (xorshift), for dense random cell sets.
fn xorshift(seed: u64) -> impl FnMut() -> u64 {
    let mut s = seed | 1;
    move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        s
    }
}

/// A random set of cells on a random aligned grid (so it can be encoded),
/// with the box it was made over: the box a record would hold for the
/// bounded object, from which a reader finds the grid again. Grids are
/// small, or more than 255 cells along x (the u16 box form); sets are
/// sparse, dense, empty or full.
fn arb_voxels() -> impl Strategy<Value = (Voxels, Aabb)> {
    let dims = prop_oneof![
        3 => prop::array::uniform3(1u32..12),
        1 => (256u32..300, 1u32..3, 1u32..3).prop_map(|(x, y, z)| [x, y, z]),
    ];
    let inset = prop::array::uniform3((0.0f64..0.49, 0.0f64..0.49));
    (arb_lattice(), 0u8..4, prop::array::uniform3(-1000i64..1000), dims, inset, any::<u64>(), 0u64..=16)
        .prop_map(|(l, level, first, dims, inset, seed, density)| {
            let s = l.cell_at(level);
            // A box strictly inside the wanted planes (by less than half a
            // cell on each face): the aligned grid is exactly them.
            let lo: [f64; 3] =
                std::array::from_fn(|a| l.origin[a] + (first[a] as f64 + 0.01 + inset[a].0) * s);
            let hi: [f64; 3] = std::array::from_fn(|a| {
                l.origin[a] + ((first[a] + i64::from(dims[a])) as f64 - 0.01 - inset[a].1) * s
            });
            let b = Aabb::from_array([lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]]);
            let g = aligned_grid(&l, level, &b).unwrap();
            assert_eq!(g.dims(), dims);
            let mut v = Voxels::empty(g.clone());
            let mut next = xorshift(seed);
            let d = g.dims();
            for z in 0..d[2] {
                for y in 0..d[1] {
                    for x in 0..d[0] {
                        if next() % 16 < density {
                            v.set_cell([x, y, z]);
                        }
                    }
                }
            }
            (v, b)
        })
}

fn cells(g: &Grid) -> impl Iterator<Item = [u32; 3]> + use<> {
    let d = g.dims();
    (0..d[2]).flat_map(move |z| (0..d[1]).flat_map(move |y| (0..d[0]).map(move |x| [x, y, z])))
}

fn in_world_boxes(v: &Voxels, p: &Point, tol: f64) -> bool {
    v.world_boxes().iter().any(|b| b.grown(tol).contains_point(p))
}

/// The form byte format-spec/lod.md says a writer emits for `v`: the
/// smaller of the bitmap and the boxes (the bitmap on a tie), boxes with u8
/// corners when every dim is at most 255.
fn spec_form(v: &Voxels) -> u8 {
    let d = v.grid().dims();
    let small = d.iter().all(|&x| x <= 255);
    let bitmap = (v.grid().cells() as usize).div_ceil(8);
    let boxes = v.boxes().len() * if small { 6 } else { 12 };
    if bitmap <= boxes {
        1
    } else if small {
        2
    } else {
        3
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    #[test]
    fn vertices_and_surface_points_lie_in_both_voxelizations(
        meshes in arb_meshes(), l in arb_lattice(), level in 0u8..3,
        samples in prop::collection::vec((0.0f64..1.0, 0.0f64..1.0), 8),
    ) {
        let g = Grid::new(&l, level, &bounds(&meshes)).unwrap();
        let filled = Voxels::of_meshes(g.clone(), &meshes);
        let surface = Voxels::of_surfaces(g, &meshes);
        prop_assert!(surface.is_subset_of(&filled).unwrap(), "the surface set is part of the filled one");
        for v in [&filled, &surface] {
            for m in &meshes {
                for p in m.vertices() {
                    prop_assert!(v.contains_point(&p), "vertex {p}");
                    prop_assert!(in_world_boxes(v, &p, 0.0), "vertex {p} exactly in a closed box");
                }
                for t in m.triangle_points() {
                    prop_assert!(v.intersects_triangle(&t));
                    for &(a, b) in &samples {
                        let p = on_triangle(&t, a, b);
                        prop_assert!(v.contains_point(&p), "surface point {p}");
                        prop_assert!(v.may_meet(&Aabb::new(p, p)), "surface point {p}");
                        // Only rounding in computing p separates it from the boxes.
                        prop_assert!(in_world_boxes(v, &p, 1e-9 * 200.0), "surface point {p}");
                    }
                }
            }
            // Every set cell lies inside the grid's bounds.
            for b in v.world_boxes() {
                prop_assert!(v.grid().bounds().contains(&b));
            }
        }
    }

    #[test]
    fn every_cell_of_a_surface_set_grown_by_the_tolerance_meets_a_triangle(
        meshes in arb_meshes(), l in arb_lattice(), level in 0u8..3,
    ) {
        let g = aligned_grid(&l, level, &bounds(&meshes)).unwrap();
        let v = Voxels::of_surfaces(g, &meshes);
        let tris = triangles(&meshes);
        prop_assert!(!v.is_empty());
        let mut n = 0;
        for c in v.cell_boxes() {
            prop_assert!(tris.iter().any(|t| intersects_triangle_box(t, &c)), "cell {c:?} touches no triangle");
            // A query that is exactly the grown cell holds it.
            prop_assert!(v.holds_a_cell_in(&c), "the grown cell {c:?} itself is not held");
            n += 1;
        }
        prop_assert_eq!(n, v.count());
    }

    #[test]
    fn a_query_holding_a_surface_cell_meets_the_surface(
        meshes in arb_meshes(), l in arb_lattice(), level in 0u8..3,
        queries in prop::collection::vec(
            (any::<prop::sample::Index>(), 0.0f64..3.0, prop::array::uniform3(-1.0f64..1.0), prop::array::uniform3(0.0f64..1.0)),
            16,
        ),
    ) {
        let g = aligned_grid(&l, level, &bounds(&meshes)).unwrap();
        let v = Voxels::of_surfaces(g, &meshes);
        let tris = triangles(&meshes);
        let set: Vec<Aabb> = v.cell_boxes().collect();
        prop_assert!(!set.is_empty());
        let s = l.cell_at(level);
        for (i, grow, shift, shrink) in queries {
            // Around a set cell: grown, moved, and squeezed on some axes (then it holds no cell).
            let c = set[i.index(set.len())];
            let mut q = c.grown(grow * s);
            for a in 0..3 {
                q.min[a] += shift[a] * grow * s;
                q.max[a] += shift[a] * grow * s;
                if shrink[a] > 0.8 {
                    q.max[a] = q.min[a] + (q.max[a] - q.min[a]) * (shrink[a] - 0.8);
                }
            }
            if v.holds_a_cell_in(&q) {
                prop_assert!(tris.iter().any(|t| intersects_triangle_box(t, &q)), "{q:?} holds a cell but meets no triangle");
            }
        }
        // A query grown around a cell holds it, so the witness does answer yes.
        prop_assert!(v.holds_a_cell_in(&set[0].grown(s)));
    }

    #[test]
    fn may_meet_never_rules_out_a_box_that_meets_a_triangle(
        meshes in arb_meshes(), l in arb_lattice(), level in 0u8..3,
        queries in prop::collection::vec(
            (any::<prop::sample::Index>(), (0.0f64..1.0, 0.0f64..1.0), prop::array::uniform3(-1.0f64..1.0), prop::array::uniform3(0.0f64..2.0), 0u8..4),
            24,
        ),
    ) {
        let g = aligned_grid(&l, level, &bounds(&meshes)).unwrap();
        let v = Voxels::of_surfaces(g, &meshes);
        let tris = triangles(&meshes);
        let s = l.cell_at(level);
        let mut met = 0;
        for (i, (a, b), dir, size, shape) in queries {
            let t = &tris[i.index(tris.len())];
            // From a point on (or a vertex of) the triangle: a point, or a box
            // with a corner there reaching away along `dir`, or a box near it.
            let p = if shape == 0 { t[i.index(3)] } else { on_triangle(t, a, b) };
            let off = Vector::new(dir[0] * size[0], dir[1] * size[1], dir[2] * size[2]) * s;
            let q = match shape {
                0 | 1 => Aabb::new(p.inf(&(p + off)), p.sup(&(p + off))),
                2 => Aabb::new(p, p),
                _ => Aabb::new(p + off, p + off).grown(s * size[0] / 4.0),
            };
            if tris.iter().any(|t| intersects_triangle_box(t, &q)) {
                met += 1;
                prop_assert!(v.may_meet(&q), "{q:?} meets a triangle but may_meet says no");
            }
        }
        prop_assert!(met > 0, "no query met a triangle: the strategy tests nothing");
        // And it does rule out what lies well away from every cell.
        let far = v.grid().bounds().grown(0.0);
        let e = far.extent().max() + 10.0 * s;
        let away = Aabb::new(far.max + Vector::repeat(e), far.max + Vector::repeat(2.0 * e));
        prop_assert!(!v.may_meet(&away));
    }

    #[test]
    fn the_inside_of_a_closed_box_is_filled_but_not_its_surface_set(
        lo in prop::array::uniform3(0.0f64..50.0), size in prop::array::uniform3(5.0f64..40.0), l in arb_lattice(),
    ) {
        let hi = [lo[0] + size[0], lo[1] + size[1], lo[2] + size[2]];
        let m = box_mesh(lo, hi);
        let v = Voxels::of_meshes(Grid::new(&l, 0, &m.aabb()).unwrap(), [&m]);
        // On the box's own bounds every cell touches or lies inside the box.
        prop_assert_eq!(v.count(), v.grid().cells());
        let g = Grid::new(&l, 0, &m.aabb().grown(10.0)).unwrap();
        let filled = Voxels::of_meshes(g.clone(), [&m]);
        let surface = Voxels::of_surfaces(g.clone(), [&m]);
        for c in cells(&g) {
            let b = g.cell_box(c);
            if m.aabb().contains_point(&b.center()) {
                prop_assert!(filled.is_set(c), "cell {c:?} inside the box");
            }
            if !m.aabb().grown(1e-6).intersects(&b) {
                prop_assert!(!filled.is_set(c), "cell {c:?} away from the box");
            }
            // A cell clear of every face (inside the box) holds no surface.
            if m.aabb().grown(-1e-6).contains(&b) {
                prop_assert!(!surface.is_set(c), "cell {c:?} of the interior is in the surface set");
            }
        }
    }

    #[test]
    fn a_level_lifted_into_the_next_is_inside_its_direct_voxelization(
        meshes in arb_meshes(), l in arb_lattice(), level in 0u8..3, up in 1u8..3,
    ) {
        let b = bounds(&meshes);
        // Clipped grids over the same box, filled sets.
        let fine = Voxels::of_meshes(Grid::new(&l, level, &b).unwrap(), &meshes);
        let coarse = Voxels::of_meshes(Grid::new(&l, level + 1, &b).unwrap(), &meshes);
        prop_assert!(fine.is_subset_of(&coarse).unwrap());
        let mut lifted = Voxels::empty(coarse.grid().clone());
        fine.lift_into(&mut lifted).unwrap();
        prop_assert!(lifted.is_subset_of(&coarse).unwrap());
        prop_assert_eq!(lifted.is_empty(), fine.is_empty());
        // Aligned grids, surface sets (what the file stores): level k + 1 of an
        // object is a finer lattice level than level k, and lifts into it.
        let gf = aligned_grid(&l, level, &b).unwrap();
        let gc = aligned_grid(&l, level + up, &b).unwrap();
        prop_assert!(gc.bounds().contains(gf.bounds()));
        let fine = Voxels::of_surfaces(gf, &meshes);
        let coarse = Voxels::of_surfaces(gc, &meshes);
        prop_assert!(fine.is_subset_of(&coarse).unwrap(), "a finer surface set leaves the coarser one");
        // The build takes a coarser bound as the finer one lifted: inside the
        // direct set, and still holding every point of every surface.
        let mut lifted = Voxels::empty(coarse.grid().clone());
        fine.lift_into(&mut lifted).unwrap();
        prop_assert!(lifted.is_subset_of(&coarse).unwrap());
        for t in meshes.iter().flat_map(|m| m.triangle_points()) {
            for w in [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0 / 3.0; 3], [0.5, 0.25, 0.25]] {
                let p = Point::from(t[0].coords * w[0] + t[1].coords * w[1] + t[2].coords * w[2]);
                prop_assert!(lifted.contains_point(&p), "a surface point {p:?} outside the lifted set");
            }
        }
    }

    #[test]
    fn a_childs_voxelization_lifts_into_its_parents(
        meshes in arb_meshes(), l in arb_lattice(), level in 0u8..2, up in 0u8..2, split in 0usize..6,
    ) {
        let split = split.clamp(1, meshes.len());
        let child = &meshes[..split];
        let parent = Voxels::of_meshes(Grid::new(&l, level + up, &bounds(&meshes)).unwrap(), &meshes);
        let c = Voxels::of_meshes(Grid::new(&l, level, &bounds(child)).unwrap(), child);
        prop_assert!(c.is_subset_of(&parent).unwrap());
        // Never the other way round: a parent does not lift into a child's smaller box.
        if !bounds(child).contains(&bounds(&meshes)) {
            prop_assert!(
                matches!(parent.is_subset_of(&c), Err(LodError::NotNested { .. })),
                "a parent's grid does not nest in its child's"
            );
        }
        // Surface sets on aligned grids nest the same way.
        let gp = aligned_grid(&l, level + up, &bounds(&meshes)).unwrap();
        let gc = aligned_grid(&l, level, &bounds(child)).unwrap();
        let parent = Voxels::of_surfaces(gp, &meshes);
        let c = Voxels::of_surfaces(gc, child);
        prop_assert!(c.is_subset_of(&parent).unwrap());
    }

    #[test]
    fn grids_nest_across_boxes_and_levels(
        l in arb_lattice(), lo in prop::array::uniform3(-30.0f64..30.0), e in prop::array::uniform3(0.0f64..60.0),
        f in prop::array::uniform3(0.0f64..1.0), g2 in prop::array::uniform3(0.0f64..1.0), j in 0u8..3, up in 0u8..3,
    ) {
        let r = Aabb::from_array([lo[0], lo[1], lo[2], lo[0] + e[0], lo[1] + e[1], lo[2] + e[2]]);
        let a: [f64; 3] = std::array::from_fn(|i| r.min[i] + e[i] * f[i].min(g2[i]));
        let b: [f64; 3] = std::array::from_fn(|i| r.min[i] + e[i] * f[i].max(g2[i]));
        let sub = Aabb::from_array([a[0], a[1], a[2], b[0], b[1], b[2]]);
        let fine = Grid::new(&l, j, &sub).unwrap();
        let coarse = Grid::new(&l, j + up, &r).unwrap();
        for c in cells(&fine) {
            let fb = fine.cell_box(c);
            let holders = cells(&coarse).filter(|&k| coarse.cell_box(k).contains(&fb)).count();
            prop_assert!(holders >= 1, "fine cell {c:?} {fb:?} lies in no coarse cell");
            // Interiors: a fine cell with volume overlaps one coarse cell only.
            if fb.volume() > 0.0 {
                let overlapping = cells(&coarse)
                    .filter(|&k| (0..3).all(|i| {
                        let cb = coarse.cell_box(k);
                        cb.min[i].max(fb.min[i]) < cb.max[i].min(fb.max[i])
                    }))
                    .count();
                prop_assert_eq!(overlapping, 1);
            }
        }
        let mut full = Voxels::empty(fine.clone());
        let d = fine.dims();
        full.set_cell([d[0] - 1, d[1] - 1, d[2] - 1]);
        prop_assert!(full.is_subset_of(&Voxels::empty(coarse.clone())).is_ok());
    }

    #[test]
    fn boxes_are_disjoint_and_cover_exactly_the_set_cells((v, _) in arb_voxels()) {
        let boxes = v.boxes();
        let mut rebuilt = Voxels::empty(v.grid().clone());
        let d = v.grid().dims();
        for b in &boxes {
            prop_assert!(b[0] < b[3] && b[1] < b[4] && b[2] < b[5]);
            prop_assert!(u32::from(b[3]) <= d[0] && u32::from(b[4]) <= d[1] && u32::from(b[5]) <= d[2]);
            for z in b[2]..b[5] {
                for y in b[1]..b[4] {
                    for x in b[0]..b[3] {
                        let c = [x, y, z].map(u32::from);
                        prop_assert!(!rebuilt.is_set(c), "boxes overlap at {c:?}");
                        rebuilt.set_cell(c);
                    }
                }
            }
        }
        prop_assert_eq!(&rebuilt, &v);
        let wb = v.world_boxes();
        prop_assert_eq!(wb.len(), boxes.len());
        let vol: f64 = wb.iter().map(Aabb::volume).sum();
        let set: f64 = cells(v.grid()).filter(|&c| v.is_set(c)).map(|c| v.grid().cell_box(c).volume()).sum();
        prop_assert!((vol - set).abs() <= 1e-9 * (1.0 + set));
    }

    #[test]
    fn the_boundary_mesh_encloses_the_solid_outward((v, _) in arb_voxels()) {
        let m = v.boundary_mesh();
        // Divergence theorem: a closed, outward mesh's signed volume is the
        // solid's (measured about the grid's corner, to keep it well conditioned).
        let o = v.grid().bounds().min;
        let signed: f64 =
            m.triangle_points().map(|[a, b, c]| (a - o).dot(&(b - o).cross(&(c - o))) / 6.0).sum();
        let vol: f64 = v.world_boxes().iter().map(Aabb::volume).sum();
        prop_assert!((signed - vol).abs() <= 1e-4 * (1.0 + vol), "{signed} against {vol}");
        prop_assert_eq!(m.triangle_count() == 0, v.is_empty());
        prop_assert!(v.faces() <= m.triangle_count() / 2);
    }

    #[test]
    fn the_measured_error_stays_within_the_cell_diagonal(
        meshes in arb_meshes(), l in arb_lattice(), level in 0u8..4,
    ) {
        let g = Grid::new(&l, level, &bounds(&meshes)).unwrap();
        for v in [Voxels::of_meshes(g.clone(), &meshes), Voxels::of_surfaces(g.clone(), &meshes)] {
            let e = measured_error(&v, &meshes, 2000);
            prop_assert!(e <= v.grid().max_cell_diagonal(), "{e} > {}", v.grid().max_cell_diagonal());
        }
    }

    #[test]
    fn inline_blobs_round_trip_in_the_smallest_form((v, b) in arb_voxels()) {
        let bytes = encode(&v);
        prop_assert_eq!(bytes.len(), encoded_len(&v));
        // The head: lattice level, form; then the payload, whose size the
        // form and the grid fix (no grid is stored).
        prop_assert_eq!(bytes[0], v.grid().level());
        prop_assert_eq!(bytes[1], spec_form(&v));
        let small = v.grid().dims().iter().all(|&d| d <= 255);
        let payload = match bytes[1] {
            1 => (v.grid().cells() as usize).div_ceil(8),
            _ => v.boxes().len() * if small { 6 } else { 12 },
        };
        prop_assert_eq!(bytes.len(), 2 + payload);
        // The reader finds the grid from the box the record holds.
        let back = decode(&bytes, v.grid().lattice(), &b).unwrap();
        prop_assert_eq!(&back, &v);
        // An aligned grid's own bounds give it back: the box may be anything
        // between the target's and the grid's.
        prop_assert_eq!(&decode(&bytes, v.grid().lattice(), v.grid().bounds()).unwrap(), &v);
        // Equal sets encode to equal bytes.
        prop_assert_eq!(encode(&back), bytes);
    }

    #[test]
    fn the_aligned_grid_is_the_whole_cells_around_the_box(
        l in arb_lattice(), level in 0u8..4, lo in prop::array::uniform3(-500.0f64..500.0),
        e in prop::array::uniform3(prop_oneof![Just(0.0), 0.0f64..100.0]),
        on_plane in prop::array::uniform3(any::<bool>()),
    ) {
        let s = l.cell_at(level);
        // Some faces exactly on a lattice plane (computed as the spec says).
        let lo: [f64; 3] = std::array::from_fn(|a| {
            if on_plane[a] { l.origin[a] + ((lo[a] - l.origin[a]) / s).floor() * s } else { lo[a] }
        });
        let b = Aabb::from_array([lo[0], lo[1], lo[2], lo[0] + e[0], lo[1] + e[1], lo[2] + e[2]]);
        let g = aligned_grid(&l, level, &b).unwrap();
        prop_assert_eq!(g.level(), level);
        prop_assert!(g.bounds().contains(&b));
        let plane = |a: usize, n: f64| l.origin[a] + n * s;
        for a in 0..3 {
            // Each face is a plane of the level, origin + n * cell, with n
            // a whole number (in f64, as the spec computes it).
            let [n0, n1] = [g.bounds().min[a], g.bounds().max[a]].map(|x| ((x - l.origin[a]) / s).round());
            prop_assert_eq!(g.bounds().min[a], plane(a, n0), "axis {}: not a lattice plane", a);
            prop_assert_eq!(g.bounds().max[a], plane(a, n1), "axis {}: not a lattice plane", a);
            prop_assert_eq!(f64::from(g.dims()[a]), n1 - n0, "axis {}: whole cells", a);
            // The last plane at or below the lower face, the first at or
            // above the upper one, at least one cell (a flat box on a plane
            // gets the cell above it).
            prop_assert!(plane(a, n0) <= b.min[a] && plane(a, n0 + 1.0) > b.min[a], "axis {}: lower face", a);
            prop_assert!(n1 == n0 + 1.0 || plane(a, n1 - 1.0) < b.max[a], "axis {}: upper face", a);
        }
    }

    #[test]
    fn decoding_never_panics_on_damaged_or_arbitrary_bytes(
        (v, b) in arb_voxels(), cut in any::<prop::sample::Index>(),
        flips in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 0..4),
        junk in prop::collection::vec(any::<u8>(), 0..300),
    ) {
        let mut out = encode(&v);
        let l = *v.grid().lattice();
        // A blob cut short is refused, or (cut between two boxes) it
        // decodes to fewer cells: no length is stored in the blob, the
        // bound entry's head holds it (format-spec/node.md, "Bounds").
        let n = cut.index(out.len());
        if let Ok(w) = decode(&out[..n], &l, &b) {
            prop_assert!(out[1] != 1 && n >= 2, "a cut bitmap decodes");
            prop_assert!(w.is_subset_of(&v).unwrap() && w.count() < v.count());
        }
        let mut longer = out.clone();
        longer.push(0);
        prop_assert!(decode(&longer, &l, &b).is_err(), "a blob with a byte too many is refused");
        for (i, x) in flips {
            let i = i.index(out.len());
            out[i] ^= x;
        }
        if let Ok(w) = decode(&out, &l, &b) {
            // Whatever decodes is a set within its own grid, which covers the box.
            prop_assert!(w.count() <= w.grid().cells());
            prop_assert!(w.grid().bounds().contains(&b));
        }
        let _ = decode(&junk, &l, &b);
    }
}

/// The aligned grid of lattice level `level` whose first cell is `first`
/// and with `dims` cells, over a unit lattice at the origin, and the box
/// (half a cell in from each face) a record would hold for it.
fn grid_at(level: u8, first: [i64; 3], dims: [u32; 3]) -> (Grid, Aabb) {
    let l = Lattice { origin: Point::origin(), cell: 1.0 };
    let s = l.cell_at(level);
    let lo = first.map(|f| (f as f64 + 0.5) * s);
    let hi: [f64; 3] = std::array::from_fn(|a| (first[a] + i64::from(dims[a])) as f64 * s - 0.5 * s);
    let b = Aabb::from_array([lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]]);
    let g = aligned_grid(&l, level, &b).unwrap();
    assert_eq!(g.dims(), dims);
    assert_eq!(g.bounds().min, Point::from(first.map(|f| f as f64 * s)));
    (g, b)
}

#[test]
fn each_form_has_the_bytes_the_spec_gives() {
    // Bitmap: one cell of one, its bit (1 payload byte against 6 for a box).
    let (g, b) = grid_at(2, [3, -1, 0], [1, 1, 1]);
    let l = *g.lattice();
    let mut v = Voxels::empty(g);
    v.set_cell([0, 0, 0]);
    let want = [2u8, 1, 0b1];
    assert_eq!(encode(&v), want);
    assert_eq!(encoded_len(&v), want.len());
    assert_eq!(decode(&want, &l, &b).unwrap(), v);
    // Bitmap, cells x fastest, then y, then z, least significant bit first:
    // 3 x 2 x 2 cells, (2, 0, 0) is bit 2, (0, 1, 1) is bit 9, (2, 1, 1) bit 11.
    let (g, b) = grid_at(0, [-2, 5, 7], [3, 2, 2]);
    let mut v = Voxels::empty(g);
    for c in [[2, 0, 0], [0, 1, 1], [2, 1, 1], [0, 0, 0], [1, 0, 0]] {
        v.set_cell(c);
    }
    let want = [0u8, 1, 0b0000_0111, 0b0000_1010];
    assert_eq!(encode(&v), want);
    assert_eq!(decode(&want, &l, &b).unwrap(), v);
    // Boxes with u8 corners: one cell of 100 x 100, at x 5, y 7: the
    // half-open cell range [5, 6) x [7, 8) x [0, 1).
    let (g, b) = grid_at(0, [-4, 0, 9], [100, 100, 1]);
    let mut v = Voxels::empty(g);
    v.set_cell([5, 7, 0]);
    let want = [0u8, 2, 5, 7, 0, 6, 8, 1];
    assert_eq!(encode(&v), want);
    assert_eq!(encoded_len(&v), want.len());
    assert_eq!(decode(&want, &l, &b).unwrap(), v);
    // Boxes with u16 corners: a row of 300 cells, the last two set.
    let (g, b) = grid_at(1, [0, 0, 0], [300, 1, 1]);
    let mut v = Voxels::empty(g);
    v.set_cell([298, 0, 0]);
    v.set_cell([299, 0, 0]);
    let mut want = vec![1u8, 3];
    for c in [298u16, 0, 0, 300, 1, 1] {
        want.extend_from_slice(&c.to_le_bytes());
    }
    assert_eq!(encode(&v), want);
    assert_eq!(encoded_len(&v), want.len());
    assert_eq!(decode(&want, &l, &b).unwrap(), v);
    // The empty set: no boxes, the head alone.
    let v = Voxels::empty(v.grid().clone());
    assert_eq!(encode(&v), [1, 3]);
    assert_eq!(decode(&[1, 3], &l, &b).unwrap(), v);
}

#[test]
fn the_box_a_record_holds_places_the_blob() {
    // The same bytes over another box are the same cells of that box's grid.
    let (g, b) = grid_at(0, [0, 0, 0], [4, 2, 1]);
    let l = *g.lattice();
    let mut v = Voxels::empty(g);
    v.set_cell([3, 1, 0]);
    let blob = encode(&v);
    assert_eq!(blob, [0, 1, 0b1000_0000]);
    assert_eq!(decode(&blob, &l, &b).unwrap(), v);
    let moved = Aabb::from_array([100.2, -7.9, 3.0, 103.6, -6.1, 3.5]);
    let w = decode(&blob, &l, &moved).unwrap();
    assert_eq!(w.grid().bounds(), &Aabb::from_array([100.0, -8.0, 3.0, 104.0, -6.0, 4.0]));
    assert_eq!(w.world_boxes(), vec![Aabb::from_array([103.0, -7.0, 3.0, 104.0, -6.0, 4.0])]);
    // Over a box whose grid has other dims the bitmap no longer fits it.
    assert!(decode(&blob, &l, &Aabb::from_array([0.5, 0.5, 0.5, 4.5, 1.5, 0.5])).is_err());
}

#[test]
fn a_blob_whose_boxes_overlap_or_leave_the_grid_is_refused() {
    let (g, b) = grid_at(0, [0, 0, 0], [100, 100, 1]);
    let l = *g.lattice();
    let mut v = Voxels::empty(g);
    v.set_cell([5, 7, 0]);
    let good = encode(&v);
    assert_eq!(good, [0, 2, 5, 7, 0, 6, 8, 1]);
    assert!(decode(&good, &l, &b).is_ok());
    let with = |head: [u8; 2], payload: &[u8]| [&head[..], payload].concat();
    // Two boxes, the second over the first.
    let overlap = with([0, 2], &[5, 7, 0, 6, 8, 1, 4, 6, 0, 7, 9, 1]);
    assert!(decode(&overlap, &l, &b).is_err(), "overlapping boxes");
    // A box past the grid, an empty box, a reversed one, a box cut short.
    for bad in [&[5u8, 7, 0, 101, 8, 1][..], &[5, 7, 0, 5, 8, 1], &[6, 7, 0, 5, 8, 1], &[5, 7, 0, 6, 8]] {
        assert!(decode(&with([0, 2], bad), &l, &b).is_err(), "box {bad:?}");
    }
    // An unknown form, and a coarser lattice level: its grid over the box is
    // one cell (128 mm), which the box leaves.
    for (at, x) in [(1usize, 0u8), (1, 9), (0, 7)] {
        let mut bad = good.clone();
        bad[at] = x;
        assert!(decode(&bad, &l, &b).is_err(), "byte {at} = {x}");
    }
    // A bitmap of the wrong size, or with a bit past the last cell.
    let (_, ob) = grid_at(0, [0, 0, 0], [3, 1, 1]);
    assert!(decode(&[0, 1, 0b111], &l, &ob).is_ok());
    for bad in [&[0u8, 1, 0b1111][..], &[0, 1], &[0, 1, 1, 0]] {
        assert!(decode(bad, &l, &ob).is_err(), "bitmap {bad:?}");
    }
    // Boxes with u8 corners on a grid more than 255 cells wide.
    let (_, wide) = grid_at(0, [0, 0, 0], [300, 1, 1]);
    assert!(decode(&[0, 2, 0, 0, 0, 1, 1, 1], &l, &wide).is_err(), "u8 corners on 300 cells");
    assert!(decode(&[0, 3, 0, 0, 0, 0, 0, 0, 1, 0, 1, 0, 1, 0], &l, &wide).is_ok());
}

#[test]
fn a_cavity_between_two_open_plates_is_not_filled() {
    let l = Lattice { origin: Point::origin(), cell: 1.0 };
    let plate = |z: f64| {
        let v = [[0.5, 0.5, z], [7.5, 0.5, z], [7.5, 7.5, z], [0.5, 7.5, z]].map(Point::from);
        Mesh::from_world(&v, vec![[0, 1, 2], [0, 2, 3]]).unwrap()
    };
    let g = Grid::new(&l, 0, &Aabb::from_array([0.0, 0.0, 0.0, 8.0, 8.0, 8.0])).unwrap();
    let v = Voxels::of_meshes(g, &[plate(0.5), plate(7.5)]);
    assert_eq!(v.count(), 2 * 64);
    assert!(!v.contains_point(&Point::new(4.0, 4.0, 4.0)));
}

#[test]
fn the_measured_error_of_a_coarse_grid_is_positive() {
    let l = Lattice { origin: Point::origin(), cell: 1.0 };
    let m = [triangle([0.0, 0.0, 0.0], [10.0, 0.0, 3.0], [0.0, 10.0, 7.0])];
    let v = Voxels::of_surfaces(Grid::new(&l, 2, &m[0].aabb()).unwrap(), &m);
    let e = measured_error(&v, &m, 1000);
    assert!(e > 0.5 && e <= v.grid().max_cell_diagonal(), "{e}");
}

#[test]
fn faces_of_hand_made_solids() {
    let l = Lattice { origin: Point::origin(), cell: 1.0 };
    let solid = |cells: &[[u32; 3]]| {
        let mut v =
            Voxels::empty(Grid::new(&l, 0, &Aabb::from_array([0.0, 0.0, 0.0, 2.0, 2.0, 2.0])).unwrap());
        cells.iter().for_each(|&c| v.set_cell(c));
        v
    };
    assert_eq!(solid(&[[0, 0, 0]]).faces(), 6);
    assert_eq!(solid(&[[0, 0, 0], [1, 0, 0]]).faces(), 6);
    assert_eq!(solid(&[[0, 0, 0], [1, 0, 0], [0, 1, 0]]).faces(), 8);
    let corner: Vec<[u32; 3]> = (0..7).map(|i| [i & 1, (i >> 1) & 1, (i >> 2) & 1]).collect();
    assert_eq!(solid(&corner).faces(), 9);
}

/// Timing on the tanker3 preset (132,456 triangles): run with `--ignored --nocapture`.
#[test]
#[ignore = "a timing report, not a claim"]
fn voxelizing_tanker3_takes_a_moment() {
    use mktree::scene::generate::{GenOptions, Preset, generate_scene};
    let scene = generate_scene(&GenOptions { preset: Preset::Tanker3, objects: None, seed: 0 }).unwrap();
    let meshes: Vec<&Mesh> = scene.objects().iter().map(|o| &o.mesh).collect();
    let b = scene.aabb();
    let l = Lattice { origin: b.min, cell: 10.0 };
    for level in [7u8, 6, 5, 4, 3] {
        let t = std::time::Instant::now();
        let g = Grid::new(&l, level, &b).unwrap();
        let v = Voxels::of_surfaces(g, meshes.iter().copied());
        let tv = t.elapsed();
        let t = std::time::Instant::now();
        let boxes = v.boxes().len();
        let tb = t.elapsed();
        let t = std::time::Instant::now();
        let e = measured_error(&v, meshes.iter().copied(), 2000);
        let te = t.elapsed();
        println!(
            "cell {} mm, dims {:?}: {} set, voxelize {tv:.3?}; {boxes} boxes {tb:.3?}; error {e:.1} (diag {:.1}) {te:.3?}",
            l.cell_at(level),
            v.grid().dims(),
            v.count(),
            v.grid().max_cell_diagonal(),
        );
    }
}

#[test]
fn a_query_unbounded_along_one_axis_is_answered_not_a_panic() {
    // A slab query: every x, the y and z of one set cell. It holds that cell.
    let l = Lattice { origin: Point::new(3.0, 0.0, 0.0), cell: 1.0 };
    let m = [triangle([0.0, 0.0, 0.0], [10.0, 0.0, 3.0], [0.0, 10.0, 7.0])];
    let g = aligned_grid(&l, 1, &m[0].aabb()).unwrap();
    let v = Voxels::of_surfaces(g, &m);
    let c = v.cell_boxes().next().unwrap();
    for far in [1e30, 1e300, f64::MAX] {
        let slab = Aabb::from_array([-far, c.min.y, c.min.z, far, c.max.y, c.max.z]);
        assert!(v.may_meet(&slab), "x = ±{far}");
        assert!(v.holds_a_cell_in(&slab), "x = ±{far}");
        assert!(v.intersects_aabb(&slab), "x = ±{far}");
    }
}

#[test]
fn a_lattice_whose_planes_do_not_advance_is_refused_not_a_hang() {
    let l = Lattice { origin: Point::origin(), cell: 1.0 };
    let b = Aabb::from_array([0.5, 0.5, 0.5, 3.5, 1.5, 1.5]);
    let mut v = Voxels::empty(aligned_grid(&l, 0, &b).unwrap());
    v.set_cell([0, 0, 0]);
    let blob = encode(&v);
    // 1e300 + n is 1e300 for every n a grid can have: planes do not advance
    // from the origin. Over a box by the origin the walks to its faces
    // would never end; over the box near 0 the planes are out of reach.
    let far = Lattice { origin: Point::new(1e300, 0.0, 0.0), cell: 1.0 };
    let near_far = Aabb::from_array([1e300, 0.5, 0.5, 1e300, 1.5, 1.5]);
    for outer in [near_far, b] {
        let blob = blob.clone();
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let _ = tx.send(decode(&blob, &far, &outer).is_ok());
        });
        let got = rx.recv_timeout(std::time::Duration::from_secs(10));
        assert_eq!(got, Ok(false), "decode over {outer:?} on a lattice whose planes do not advance");
    }
}
