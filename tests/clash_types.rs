//! Claim: a typed clash test finds each kind of clash between the sets its
//! selectors choose, with its measure: hard (penetration above the
//! tolerance, the smallest side of the intersection's box), clearance (the
//! least distance, strictly below d, with the closest points), touch (only
//! when asked), duplicate (the same geometry within a tolerance); a is
//! always from set A (docs/clash.md).

mod common;

use common::{box_mesh, mem_db};
use mktree::clash::{ClashKind, ClashTest, GroupBy, TestKind, group, run_test};
use mktree::scene::{Key, Object, Scene};
use mktree::{BuildParams, CreateOptions};

fn obj(name: &str, class: &str, lo: [f64; 3], hi: [f64; 3]) -> Object {
    Object::new(name, box_mesh(lo, hi))
        .with_key(Key::bytes(name).unwrap())
        .with_payload(format!("{{\"class\": \"{class}\"}}").into_bytes())
}

/// A wall 200 mm thick and pipes against it, one of each case.
fn scene() -> Scene {
    Scene::new(vec![
        obj("WALL-1", "IfcWall", [0.0, 0.0, 0.0], [200.0, 5000.0, 3000.0]),
        // Through the wall: 120 x 120 across a wall 200 thick.
        obj("PIPE-1", "IfcPipeSegment", [-500.0, 1000.0, 1000.0], [700.0, 1120.0, 1120.0]),
        // On the wall's face.
        obj("PIPE-2", "IfcPipeSegment", [200.0, 2000.0, 1000.0], [900.0, 2100.0, 1100.0]),
        // 30 mm from it.
        obj("PIPE-3", "IfcPipeSegment", [230.0, 3000.0, 1000.0], [900.0, 3100.0, 1100.0]),
        // 50 mm from it: not below a clearance of 50.
        obj("PIPE-4", "IfcPipeSegment", [250.0, 4000.0, 1000.0], [900.0, 4100.0, 1100.0]),
        // Inside the wall, touching no face: 100 x 100 x 100.
        obj("PIPE-5", "IfcPipeSegment", [50.0, 4500.0, 100.0], [150.0, 4600.0, 200.0]),
        // 1 mm into the wall: below a tolerance of 2.
        obj("PIPE-6", "IfcPipeSegment", [199.0, 200.0, 1000.0], [900.0, 300.0, 1100.0]),
        // The wall again, 0.004 mm higher.
        obj("COPY-WALL-1", "IfcWall", [0.0, 0.0, 0.004], [200.0, 5000.0, 3000.004]),
        // Far away.
        obj("DUCT-1", "IfcDuctSegment", [5000.0, 0.0, 0.0], [5300.0, 200.0, 200.0]),
    ])
}

fn test(kind: TestKind) -> ClashTest {
    ClashTest {
        a: vec!["name:PIPE*".parse().unwrap()],
        b: Some(vec!["key:WALL-1".parse().unwrap()]),
        kind,
        tolerance: 2.0,
        ..Default::default()
    }
}

fn found(run: &mktree::clash::ClashRun) -> Vec<(String, ClashKind)> {
    run.clashes.iter().map(|c| (c.a.to_string(), c.kind)).collect()
}

#[test]
fn hard_clashes_penetrate_past_the_tolerance_and_touches_wait_to_be_asked() {
    let (db, _) = mem_db(&scene(), &BuildParams::default(), CreateOptions::default());
    let r = db.begin_read().unwrap();
    let run = run_test(&r, &test(TestKind::Hard)).unwrap();
    assert_eq!(found(&run), vec![("PIPE-1".into(), ClashKind::Hard), ("PIPE-5".into(), ClashKind::Hard)]);
    let depth = |run: &mktree::clash::ClashRun, a: &str| {
        run.clashes.iter().find(|c| c.a.to_string() == a).map(|c| c.depth).unwrap()
    };
    assert!((depth(&run, "PIPE-1") - 120.0).abs() < 1e-9);
    assert!((depth(&run, "PIPE-5") - 100.0).abs() < 1e-9, "wholly inside: its own box");
    let c = &run.clashes[0];
    assert_eq!(c.b, Key::bytes("WALL-1").unwrap(), "b is from set B");
    let o = c.overlap.unwrap();
    assert_eq!(o.to_array(), [0.0, 1000.0, 1000.0, 200.0, 1120.0, 1120.0]);
    assert_eq!(c.point.x, 100.0);

    let with_touch = run_test(&r, &ClashTest { touch: true, ..test(TestKind::Hard) }).unwrap();
    assert_eq!(
        found(&with_touch),
        vec![
            ("PIPE-1".into(), ClashKind::Hard),
            ("PIPE-2".into(), ClashKind::Touch),
            ("PIPE-5".into(), ClashKind::Hard),
            ("PIPE-6".into(), ClashKind::Touch),
        ]
    );
    assert_eq!(with_touch.clashes[1].depth, 0.0, "face to face");
    assert!((with_touch.clashes[3].depth - 1.0).abs() < 1e-9, "1 mm in, below the tolerance");
    let strict = run_test(&r, &ClashTest { tolerance: 0.5, ..test(TestKind::Hard) }).unwrap();
    assert!(found(&strict).contains(&("PIPE-6".into(), ClashKind::Hard)), "above a tolerance of 0.5");
}

#[test]
fn clearance_reports_distances_below_d_with_the_closest_points() {
    let (db, _) = mem_db(&scene(), &BuildParams::default(), CreateOptions::default());
    let r = db.begin_read().unwrap();
    let run = run_test(&r, &ClashTest { distance: 50.0, ..test(TestKind::Clearance) }).unwrap();
    assert_eq!(
        found(&run),
        vec![
            ("PIPE-1".into(), ClashKind::Hard),
            ("PIPE-3".into(), ClashKind::Clearance),
            ("PIPE-5".into(), ClashKind::Hard),
        ],
        "PIPE-4 lies at 50 mm: not below 50"
    );
    let c = &run.clashes[1];
    assert!((c.distance - 30.0).abs() < 1e-9);
    let [p, q] = c.closest.unwrap();
    assert!((p.x - 230.0).abs() < 1e-9 && (q.x - 200.0).abs() < 1e-9, "a's point first: {p} {q}");
    assert!((c.point.x - 215.0).abs() < 1e-9);
    let wider = run_test(&r, &ClashTest { distance: 50.001, ..test(TestKind::Clearance) }).unwrap();
    assert!(found(&wider).contains(&("PIPE-4".into(), ClashKind::Clearance)));
}

#[test]
fn duplicates_and_payload_selectors() {
    let (db, _) = mem_db(&scene(), &BuildParams::default(), CreateOptions::default());
    let r = db.begin_read().unwrap();
    let walls = ClashTest {
        a: vec!["class:IfcWall".parse().unwrap()],
        b: None,
        kind: TestKind::Duplicate,
        tolerance: 0.01,
        ..Default::default()
    };
    let run = run_test(&r, &walls).unwrap();
    assert_eq!(run.clashes.len(), 1);
    let c = &run.clashes[0];
    assert_eq!(
        (c.a.to_string(), c.b.to_string(), c.kind),
        ("COPY-WALL-1".into(), "WALL-1".into(), ClashKind::Duplicate)
    );
    let tight = run_test(&r, &ClashTest { tolerance: 0.001, ..walls.clone() }).unwrap();
    assert!(tight.clashes.is_empty(), "0.004 mm apart is past 0.001");
    // A against itself by payload: walls against walls are a hard clash too.
    let hard = run_test(&r, &ClashTest { kind: TestKind::Hard, ..walls }).unwrap();
    assert_eq!(hard.clashes.len(), 1);
    assert_eq!(hard.stats.in_a, 2);
}

#[test]
fn the_whole_file_against_itself_finds_each_pair_once_and_groups_cover_every_clash() {
    let (db, _) = mem_db(&scene(), &BuildParams::default(), CreateOptions::default());
    let r = db.begin_read().unwrap();
    let all = ClashTest { kind: TestKind::Clearance, distance: 50.0, touch: true, ..Default::default() };
    let run = run_test(&r, &all).unwrap();
    let mut pairs: Vec<(String, String)> =
        run.clashes.iter().map(|c| (c.a.to_string(), c.b.to_string())).collect();
    assert!(run.clashes.iter().all(|c| c.a < c.b), "both in both sets: the smaller key first");
    pairs.dedup();
    assert_eq!(pairs.len(), run.clashes.len());
    // Every pipe but PIPE-4 against each wall, and the walls against each other.
    assert_eq!(run.clashes.len(), 2 * 5 + 1);
    for by in [GroupBy::ObjectA, GroupBy::Proximity(500.0), GroupBy::KeyPrefix(4), GroupBy::None] {
        let groups = group(&run.clashes, by);
        let mut members: Vec<usize> = groups.iter().flat_map(|g| g.members.clone()).collect();
        members.sort_unstable();
        assert_eq!(members, (0..run.clashes.len()).collect::<Vec<_>>(), "{by}");
    }
    assert_eq!(group(&run.clashes, GroupBy::KeyPrefix(4)).len(), 2, "COPY and PIPE");
}
