//! Whether a mesh bounds a solid: every edge shared by exactly two triangles.

use crate::scene::Mesh;
use std::collections::HashMap;

/// True when every edge of the mesh is shared by exactly two triangles.
/// Vertices at the same stored position count as one (importers may split
/// them at seams), and triangles with a repeated vertex are ignored (they
/// have no area and bound nothing).
pub fn is_closed(mesh: &Mesh) -> bool {
    let mut weld: HashMap<[u32; 3], u32> = HashMap::with_capacity(mesh.vertex_count());
    let id: Vec<u32> = mesh
        .offsets()
        .iter()
        .map(|o| {
            let n = weld.len() as u32;
            *weld.entry(o.map(f32::to_bits)).or_insert(n)
        })
        .collect();
    let mut edges: HashMap<(u32, u32), u32> = HashMap::with_capacity(mesh.triangle_count() * 2);
    let mut any = false;
    for t in mesh.triangles() {
        let v = t.map(|i| id[i as usize]);
        if v[0] == v[1] || v[1] == v[2] || v[2] == v[0] {
            continue;
        }
        any = true;
        for (a, b) in [(v[0], v[1]), (v[1], v[2]), (v[2], v[0])] {
            *edges.entry((a.min(b), a.max(b))).or_insert(0) += 1;
        }
    }
    any && edges.values().all(|&n| n == 2)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::geom::Point;

    pub(crate) fn cube_mesh(lo: [f64; 3], hi: [f64; 3]) -> Mesh {
        Mesh::of_box(&crate::geom::Aabb::new(lo.into(), hi.into())).unwrap()
    }

    #[test]
    fn a_cube_is_closed_and_a_cube_missing_a_triangle_is_not() {
        let c = cube_mesh([0.0; 3], [1.0; 3]);
        assert!(is_closed(&c));
        let v: Vec<Point> = c.vertices().collect();
        let open = Mesh::from_world(&v, c.triangles()[1..].to_vec()).unwrap();
        assert!(!is_closed(&open));
    }

    #[test]
    fn split_vertices_at_the_same_position_are_welded() {
        let c = cube_mesh([0.0; 3], [1.0; 3]);
        // Every triangle gets its own three vertices.
        let v: Vec<Point> = c.triangle_points().flatten().collect();
        let t = (0..c.triangle_count() as u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
        assert!(is_closed(&Mesh::from_world(&v, t).unwrap()));
    }
}
