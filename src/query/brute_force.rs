//! The oracles of the tests: every query answered by testing every object
//! (or pair) of the scene exactly, with no tree and no file, by the same
//! contact rule as the queries (closed sets, touching counts).

use super::nearest::Near;
use super::rank::Rank;
use super::ray::{RayHit, hit, rank};
use super::select::{Region, Selection, Triangles};
use crate::geom::{Point, Pose, Ray};
use crate::scene::{Key, Mesh, ObjectId, Scene};

/// The oracle for scenes too large to hold: objects are offered one at a
/// time, in id order (as a streaming import hands them over), and each is
/// tested against every probe, exactly, after its box. One pass over the
/// scene answers any number of probes.
pub struct ScanOracle<'p> {
    probes: &'p [&'p dyn Selection],
    answers: Vec<Vec<ObjectId>>,
    next: u32,
}

impl<'p> ScanOracle<'p> {
    /// An oracle for `probes`, with no object offered yet.
    pub fn new(probes: &'p [&'p dyn Selection]) -> ScanOracle<'p> {
        ScanOracle { probes, answers: vec![Vec::new(); probes.len()], next: 0 }
    }

    /// Tests the next object, whose id is the count of objects offered before.
    pub fn offer(&mut self, mesh: &Mesh) {
        let (id, aabb, mut tested) = (ObjectId(self.next), mesh.aabb(), 0);
        for (probe, answer) in self.probes.iter().zip(&mut self.answers) {
            if probe.may_meet_box(&aabb) && probe.meets_mesh(mesh, &mut tested) {
                answer.push(id);
            }
        }
        self.next += 1;
    }

    /// Objects offered.
    pub fn objects(&self) -> u32 {
        self.next
    }

    /// Per probe, the ids of the objects that meet it, ascending.
    pub fn answers(self) -> Vec<Vec<ObjectId>> {
        self.answers
    }
}

fn all<P: Selection + ?Sized>(scene: &Scene, probe: &P) -> Vec<ObjectId> {
    let mut n = 0;
    (0..scene.len() as u32)
        .map(ObjectId)
        .filter(|&id| scene.object(id).is_some_and(|o| probe.meets_mesh(&o.mesh, &mut n)))
        .collect()
}

/// The objects whose triangles meet the closed `region` (touching counts).
pub fn brute_force_region(scene: &Scene, region: &Region) -> Vec<ObjectId> {
    all(scene, region)
}

/// The objects within `clearance` of `mesh` under `pose` (touching at 0; sorted).
pub fn brute_force_collide(
    scene: &Scene,
    mesh: &Mesh,
    pose: &Pose,
    clearance: f64,
    exclude: Option<ObjectId>,
) -> Result<Vec<ObjectId>, crate::geom::ShapeError> {
    let probe = Triangles::posed(mesh, pose, clearance)?;
    Ok(all(scene, &probe).into_iter().filter(|&id| Some(id) != exclude).collect())
}

/// Every pair (a, b), a < b, of objects within `clearance` (touching at 0; sorted).
pub fn brute_force_clash(
    scene: &Scene,
    clearance: f64,
) -> Result<Vec<(ObjectId, ObjectId)>, crate::geom::ShapeError> {
    let mut pairs = Vec::new();
    let mut n = 0;
    for (i, a) in scene.objects().iter().enumerate() {
        let probe = Triangles::posed(&a.mesh, &Pose::default(), clearance)?;
        for (j, b) in scene.objects().iter().enumerate().skip(i + 1) {
            if probe.meets_mesh(&b.mesh, &mut n) {
                pairs.push((ObjectId(i as u32), ObjectId(j as u32)));
            }
        }
    }
    Ok(pairs)
}

/// Every object with its distance from `point` (the same numbers as
/// `ReadTransaction::nearest`), nearest first, ties by id.
pub fn brute_force_nearest(scene: &Scene, point: &Point) -> Vec<Near> {
    ranked(scene, &Rank::Nearest(*point))
        .into_iter()
        .map(|(object, distance)| Near { object, key: key_of(scene, object), distance })
        .collect()
}

fn key_of(scene: &Scene, id: ObjectId) -> Key {
    scene.key(id).unwrap_or(Key::Int(u64::from(id.0)))
}

/// Every object `ray` meets, followed past the scene's box (or to its
/// maximum), with the distance it first meets each: nearest first, ties by id.
pub fn brute_force_ray(scene: &Scene, ray: &Ray) -> Vec<RayHit> {
    ranked(scene, &rank(ray, &scene.aabb()))
        .into_iter()
        .map(|(id, t)| hit(ray, (id, key_of(scene, id)), t))
        .collect()
}

fn ranked(scene: &Scene, rank: &Rank) -> Vec<(ObjectId, f64)> {
    let mut n = 0;
    let mut all: Vec<(ObjectId, f64)> = (0..scene.len() as u32)
        .filter_map(|i| Some((ObjectId(i), rank.mesh_distance(&scene.object(ObjectId(i))?.mesh, &mut n)?)))
        .collect();
    all.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
    all
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Aabb;
    use crate::scene::Object;

    #[test]
    fn a_scan_answers_as_the_whole_scene_does() {
        let scene = Scene::new(
            (0..40)
                .map(|i| {
                    let lo =
                        Point::new(f64::from(i % 7) * 30.0, f64::from(i / 7) * 25.0, f64::from(i % 3) * 10.0);
                    let b = Aabb::new(lo, lo + crate::geom::Vector::new(20.0, 15.0, 12.0));
                    Object::new(format!("b{i}"), Mesh::of_box(&b).expect("a box"))
                })
                .collect(),
        );
        let regions = [
            Region::Box(Aabb::from_array([0.0, 0.0, 0.0, 55.0, 60.0, 30.0])),
            Region::Box(Aabb::from_array([100.0, 40.0, 5.0, 101.0, 41.0, 6.0])),
            Region::Box(Aabb::from_array([-50.0, -50.0, -50.0, -40.0, -40.0, -40.0])),
        ];
        let probes: Vec<&dyn Selection> = regions.iter().map(|r| r as &dyn Selection).collect();
        let mut oracle = ScanOracle::new(&probes);
        for o in scene.objects() {
            oracle.offer(&o.mesh);
        }
        assert_eq!(oracle.objects(), 40);
        let answers = oracle.answers();
        for (region, answer) in regions.iter().zip(&answers) {
            assert_eq!(*answer, brute_force_region(&scene, region));
        }
        assert!(!answers[0].is_empty() && answers[2].is_empty());
    }
}
