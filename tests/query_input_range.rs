//! Claim (issue 39): every query entry point refuses a point outside the
//! file's coordinate range [-2^53, 2^53] mm (format-spec/geometry.md) with
//! `QueryError::OutOfRange`, and a box that is inverted with one error,
//! whether asked through `query_box`, `query_region` or a batch `Request`;
//! from the edge of the range, nearest distances come out finite (never
//! NaN, which JSON prints as `null`).

use mktree::bulk::BuildParams;
use mktree::db::CreateOptions;
use mktree::geom::{Aabb, Camera, Frustum, Point, Pose, Ray, ShapeError, Sphere, Vector};
use mktree::query::{CollideOptions, QueryError, Region, Request, answer_request, collide, query_region};

mod common;

use common::{box_mesh, grid_scene, mem_db};

const EDGE: f64 = 9_007_199_254_740_992.0;

fn out_of_range<T: std::fmt::Debug>(r: Result<T, QueryError>) -> bool {
    matches!(r, Err(QueryError::OutOfRange { .. }))
}

#[test]
fn a_far_point_is_refused_by_every_query_and_the_edge_answers_finite_distances() {
    let (db, _) = mem_db(&grid_scene(64), &BuildParams::paper(), CreateOptions::default());
    let r = db.begin_read().unwrap();
    let far = Point::new(1e160, 0.0, 0.0);

    assert!(out_of_range(r.nearest(far, None).map(|_| ())));
    let req = Request::Nearest { point: [1e160, 0.0, 0.0], k: 2 };
    assert!(out_of_range(answer_request(&r, &req, None)));
    assert!(out_of_range(r.query_box(&Aabb::new(Point::origin(), Point::new(EDGE * 2.0, 1.0, 1.0)))));
    let sphere = Region::Sphere(Sphere::new(far, 1.0).unwrap());
    assert!(out_of_range(query_region(&r, &sphere, &Default::default(), None)));
    let huge = Region::Sphere(Sphere::new(Point::origin(), 1e300).unwrap());
    assert!(matches!(query_region(&r, &huge, &Default::default(), None), Err(QueryError::TooLong { .. })));
    let ray = Ray::new(far, Vector::new(-1.0, 0.0, 0.0), None).unwrap();
    assert!(out_of_range(r.ray(&ray, None).map(|_| ())));
    assert!(out_of_range(r.first_hit(&ray, None)));
    let camera = Camera {
        eye: Point::new(-1000.0, 50.0, 50.0),
        target: Point::new(0.0, 50.0, 50.0),
        fov_deg: 60.0,
        aspect: 1.0,
        near: 1.0,
        far: 1e20,
    };
    let frustum = Region::Frustum(Box::new(Frustum::from_camera(&camera).unwrap()));
    assert!(out_of_range(query_region(&r, &frustum, &Default::default(), None)));
    let pose = Pose::from_degrees([1e200, 0.0, 0.0], [0.0; 3]).unwrap();
    let mesh = box_mesh([0.0; 3], [10.0; 3]);
    let opts = CollideOptions { query: Default::default(), clearance: 0.0, exclude: None };
    assert!(out_of_range(collide(&r, &mesh, &pose, &opts, None)));

    // The edge of the range is in it: the distances are finite and ordered.
    let near: Vec<_> =
        r.nearest(Point::new(EDGE, 0.0, -EDGE), None).unwrap().take(2).map(|n| n.unwrap()).collect();
    assert_eq!(near.len(), 2);
    assert!(near.iter().all(|n| n.distance.is_finite() && n.distance > 1e15), "{near:?}");
    assert!(near[0].distance <= near[1].distance);
    let req = Request::Nearest { point: [-EDGE, EDGE, EDGE], k: 2 };
    let a = answer_request(&r, &req, None).unwrap();
    assert!(a.distances.unwrap().iter().all(|d| d.is_finite()));
}

#[test]
fn an_inverted_box_is_one_error_through_every_entry() {
    let (db, _) = mem_db(&grid_scene(64), &BuildParams::paper(), CreateOptions::default());
    let r = db.begin_read().unwrap();
    let inverted = [100.0, 0.0, 0.0, 0.0, 100.0, 100.0];
    let direct = r.query_box(&Aabb::from_array(inverted)).unwrap_err();
    assert!(matches!(direct, QueryError::Shape(ShapeError::Invalid { .. })), "{direct}");
    let region = query_region(&r, &Region::Box(Aabb::from_array(inverted)), &Default::default(), None);
    let batch = answer_request(&r, &Request::Box { aabb: inverted, lod: None, budget: None }, None);
    assert_eq!(region.unwrap_err().to_string(), direct.to_string());
    assert_eq!(batch.unwrap_err().to_string(), direct.to_string());
    assert!(direct.to_string().contains("inverted"), "{direct}");
    // A flat box (x0 == x1) is a box.
    assert!(r.query_box(&Aabb::from_array([50.0, 0.0, 0.0, 50.0, 100.0, 100.0])).is_ok());
}
