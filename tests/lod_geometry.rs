//! The voxel levels of detail are conservative and nest: every point of the
//! geometry lies in the voxel solid, every point of the solid lies within the
//! grid's cell diagonal of the geometry, a level lifts into the next coarser
//! one and into a parent's grid, and blobs round-trip and never panic.

mod common;

use common::{box_mesh, triangle};
use mktree::geom::{Aabb, Point};
use mktree::lod::{Form, Grid, Lattice, LodError, Voxels, decode, decode_objects, encode, measured_error};
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

/// A random set of cells on a random small grid.
fn arb_voxels() -> impl Strategy<Value = Voxels> {
    (arb_lattice(), prop::array::uniform3(0.0f64..30.0), any::<u64>(), 1u64..4).prop_map(
        |(l, e, seed, density)| {
            let g = Grid::new(&l, 0, &Aabb::from_array([0.0, 0.0, 0.0, e[0], e[1], e[2]])).unwrap();
            let mut v = Voxels::empty(g.clone());
            let mut s = seed | 1;
            let d = g.dims();
            for z in 0..d[2] {
                for y in 0..d[1] {
                    for x in 0..d[0] {
                        s ^= s << 13;
                        s ^= s >> 7;
                        s ^= s << 17;
                        if s % 4 < density {
                            v.set_cell([x, y, z]);
                        }
                    }
                }
            }
            v
        },
    )
}

fn in_world_boxes(v: &Voxels, p: &Point, tol: f64) -> bool {
    v.world_boxes().iter().any(|b| b.grown(tol).contains_point(p))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn vertices_and_surface_points_lie_in_the_voxel_solid(
        meshes in arb_meshes(), l in arb_lattice(), level in 0u8..3,
        samples in prop::collection::vec((0.0f64..1.0, 0.0f64..1.0), 8),
    ) {
        let g = Grid::new(&l, level, &bounds(&meshes)).unwrap();
        let v = Voxels::of_meshes(g, &meshes);
        for m in &meshes {
            for p in m.vertices() {
                prop_assert!(v.contains_point(&p), "vertex {p}");
                prop_assert!(in_world_boxes(&v, &p, 0.0), "vertex {p} exactly in a closed box");
            }
            for t in m.triangle_points() {
                prop_assert!(v.intersects_triangle(&t));
                for &(a, b) in &samples {
                    let (a, b) = if a + b > 1.0 { (1.0 - a, 1.0 - b) } else { (a, b) };
                    let p = t[0] + (t[1] - t[0]) * a + (t[2] - t[0]) * b;
                    prop_assert!(v.contains_point(&p), "surface point {p}");
                    // Only rounding in computing p separates it from the boxes.
                    prop_assert!(in_world_boxes(&v, &p, 1e-9 * 200.0), "surface point {p}");
                }
            }
        }
        // Every set cell lies inside the grid's bounds.
        for b in v.world_boxes() {
            prop_assert!(v.grid().bounds().contains(&b));
        }
    }

    #[test]
    fn the_inside_of_a_closed_box_is_filled(
        lo in prop::array::uniform3(0.0f64..50.0), size in prop::array::uniform3(5.0f64..40.0), l in arb_lattice(),
    ) {
        let hi = [lo[0] + size[0], lo[1] + size[1], lo[2] + size[2]];
        let m = box_mesh(lo, hi);
        let v = Voxels::of_meshes(Grid::new(&l, 0, &m.aabb()).unwrap(), [&m]);
        // On the box's own bounds every cell touches or lies inside the box.
        prop_assert_eq!(v.count(), v.grid().cells());
        let g = Grid::new(&l, 0, &m.aabb().grown(10.0)).unwrap();
        let v = Voxels::of_meshes(g.clone(), [&m]);
        let d = g.dims();
        for c in (0..d[0]).flat_map(|x| (0..d[1]).flat_map(move |y| (0..d[2]).map(move |z| [x, y, z]))) {
            let b = g.cell_box(c);
            if m.aabb().contains_point(&b.center()) {
                prop_assert!(v.is_set(c), "cell {c:?} inside the box");
            }
            if !m.aabb().grown(1e-6).intersects(&b) {
                prop_assert!(!v.is_set(c), "cell {c:?} away from the box");
            }
        }
    }

    #[test]
    fn a_level_lifted_into_the_next_is_inside_its_direct_voxelization(
        meshes in arb_meshes(), l in arb_lattice(), level in 0u8..3,
    ) {
        let b = bounds(&meshes);
        let fine = Voxels::of_meshes(Grid::new(&l, level, &b).unwrap(), &meshes);
        let coarse = Voxels::of_meshes(Grid::new(&l, level + 1, &b).unwrap(), &meshes);
        prop_assert!(fine.is_subset_of(&coarse).unwrap());
        // The lift itself is the coarser solid at most.
        let mut lifted = Voxels::empty(coarse.grid().clone());
        fine.lift_into(&mut lifted).unwrap();
        prop_assert!(lifted.is_subset_of(&coarse).unwrap());
    }

    #[test]
    fn a_childs_voxelization_lifts_into_its_parents(
        meshes in arb_meshes(), l in arb_lattice(), level in 0u8..2, up in 0u8..2, split in 0usize..6,
    ) {
        let split = split.min(meshes.len() - 1).max(1).min(meshes.len());
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
        let cells = |g: &Grid| {
            let d = g.dims();
            (0..d[0]).flat_map(move |x| (0..d[1]).flat_map(move |y| (0..d[2]).map(move |z| [x, y, z])))
        };
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
        // Every coarse cell is covered by the fine grid's cells inside it on
        // the sub-box: lifting the full fine set gives a non-empty coarse set.
        let mut full = Voxels::empty(fine.clone());
        let d = fine.dims();
        full.set_cell([d[0] - 1, d[1] - 1, d[2] - 1]);
        prop_assert!(full.is_subset_of(&Voxels::empty(coarse.clone())).is_ok());
    }

    #[test]
    fn boxes_are_disjoint_and_cover_exactly_the_set_cells(v in arb_voxels()) {
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
        let cells: f64 = (0..v.grid().cells() as usize)
            .map(|i| {
                let c = [i as u32 % d[0], (i as u32 / d[0]) % d[1], i as u32 / (d[0] * d[1])];
                if v.is_set(c) { v.grid().cell_box(c).volume() } else { 0.0 }
            })
            .sum();
        prop_assert!((vol - cells).abs() <= 1e-9 * (1.0 + cells));
    }

    #[test]
    fn the_boundary_mesh_encloses_the_solid_outward(v in arb_voxels()) {
        let m = v.boundary_mesh();
        // Divergence theorem: a closed, outward mesh's signed volume is the solid's.
        let signed: f64 = m.triangle_points().map(|[a, b, c]| a.coords.dot(&b.coords.cross(&c.coords)) / 6.0).sum();
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
        let v = Voxels::of_meshes(g, &meshes);
        let e = measured_error(&v, &meshes, 2000);
        prop_assert!(e <= v.grid().max_cell_diagonal(), "{e} > {}", v.grid().max_cell_diagonal());
    }

    #[test]
    fn both_forms_round_trip(v in arb_voxels(), bitmap in any::<bool>(), id in any::<u32>()) {
        let form = if bitmap { Form::Bitmap } else { Form::Boxes };
        let mut out = Vec::new();
        encode(&v, form, &mut out);
        prop_assert_eq!(out.len(), mktree::lod::encoded_len(&v, form));
        prop_assert_eq!(out.len() % 4, 0);
        let (back, used) = decode(&out, v.grid().lattice()).unwrap();
        prop_assert_eq!(used, out.len());
        prop_assert_eq!(&back, &v);
        let mut objs = Vec::new();
        mktree::lod::encode_objects(&[(id, &v), (7, &back)], form, &mut objs);
        let got = decode_objects(&objs, v.grid().lattice()).unwrap();
        prop_assert_eq!(got, vec![(id, v.clone()), (7, v)]);
    }

    #[test]
    fn decoding_never_panics_on_damaged_or_arbitrary_bytes(
        v in arb_voxels(), bitmap in any::<bool>(), cut in any::<prop::sample::Index>(),
        flips in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 0..4),
        junk in prop::collection::vec(any::<u8>(), 0..300),
    ) {
        let form = if bitmap { Form::Bitmap } else { Form::Boxes };
        let mut out = Vec::new();
        encode(&v, form, &mut out);
        let l = *v.grid().lattice();
        let n = cut.index(out.len());
        prop_assert!(decode(&out[..n], &l).is_err(), "a truncated blob is refused");
        for (i, x) in flips {
            let i = i.index(out.len());
            out[i] ^= x;
        }
        let _ = decode(&out, &l);
        let _ = decode_objects(&out, &l);
        let _ = decode(&junk, &l);
        let _ = decode_objects(&junk, &l);
    }
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
    let v = Voxels::of_meshes(Grid::new(&l, 2, &m[0].aabb()).unwrap(), &m);
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
#[ignore]
fn voxelizing_tanker3_takes_a_moment() {
    use mktree::scene::generate::{GenOptions, Preset, generate_scene};
    let scene = generate_scene(&GenOptions { preset: Preset::Tanker3, objects: None, seed: 0 }).unwrap();
    let meshes: Vec<&Mesh> = scene.objects().iter().map(|o| &o.mesh).collect();
    let b = scene.aabb();
    let l = Lattice { origin: b.min, cell: 10.0 };
    for level in [7u8, 6, 5, 4, 3] {
        let t = std::time::Instant::now();
        let g = Grid::new(&l, level, &b).unwrap();
        let v = Voxels::of_meshes(g, meshes.iter().copied());
        let tv = t.elapsed();
        let t = std::time::Instant::now();
        let boxes = v.boxes().len();
        let tb = t.elapsed();
        let t = std::time::Instant::now();
        let faces = v.faces();
        let tf = t.elapsed();
        let t = std::time::Instant::now();
        let e = measured_error(&v, meshes.iter().copied(), 2000);
        let te = t.elapsed();
        println!(
            "cell {} mm, dims {:?}: {} set, voxelize {:.3?}; {} boxes {:.3?}; {} faces {:.3?}; error {:.1} (diag {:.1}) {:.3?}",
            l.cell_at(level),
            v.grid().dims(),
            v.count(),
            tv,
            boxes,
            tb,
            faces,
            tf,
            e,
            v.grid().max_cell_diagonal(),
            te
        );
    }
}
