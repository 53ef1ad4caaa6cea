//! A catalog of 20 files answers a region query with the union of the
//! files' own answers, keys qualified by model, and opens (over HTTP:
//! requests) only the files whose root box the region may meet; a file
//! that moved on from the catalog's commit is refused, not mixed in
//! (issue 36 item 4, format-spec/catalog.md).

mod common;

use std::collections::BTreeSet;
use std::path::Path;

use mktree::bulk::BuildParams;
use mktree::catalog::{Catalog, CatalogError, CatalogOptions};
use mktree::db::{CreateOptions, Database};
use mktree::geom::{Aabb, Point};
use mktree::scene::generate::{GenOptions, Preset, generate_scene};
use mktree::scene::{Key, Mesh, Object, Scene};
use mktree::{QueryOptions, Region};

const MODELS: usize = 20;

/// Tanker1 moved by `offset`, keyed by its ids as byte strings.
fn moved(base: &Scene, offset: [f64; 3]) -> Scene {
    Scene::new(
        base.objects()
            .iter()
            .enumerate()
            .map(|(i, o)| {
                let v: Vec<Point> = o
                    .mesh
                    .vertices()
                    .map(|p| Point::new(p.x + offset[0], p.y + offset[1], p.z + offset[2]))
                    .collect();
                let mesh = Mesh::from_world(&v, o.mesh.triangles().to_vec()).expect("a moved mesh");
                Object::new(o.name.clone(), mesh).with_key(Key::bytes(format!("part-{i}")).expect("short"))
            })
            .collect(),
    )
}

fn write(path: &Path, scene: &Scene) {
    let db = Database::create(path, CreateOptions::default()).expect("create");
    let mut w = db.begin_write().expect("write");
    w.bulk_load(scene, &BuildParams::default(), &|_| {}).expect("bulk load");
    w.commit().expect("commit");
}

/// 20 copies of tanker1 on a 5 x 4 grid with gaps, as m00.mkt .. m19.mkt
/// in `dir`; the catalog (paths relative to `dir`) and the grid's pitch.
fn twenty_files(dir: &Path) -> (Catalog, [f64; 2]) {
    let base =
        generate_scene(&GenOptions { preset: Preset::Tanker1, objects: None, seed: 0 }).expect("preset");
    let b = base.aabb();
    let pitch = [(b.max.x - b.min.x) * 1.5, (b.max.y - b.min.y) * 1.5];
    let names: Vec<String> = (0..MODELS).map(|i| format!("m{i:02}")).collect();
    for (i, name) in names.iter().enumerate() {
        let offset = [pitch[0] * (i % 5) as f64, pitch[1] * (i / 5) as f64, 0.0];
        write(&dir.join(format!("{name}.mkt")), &moved(&base, offset));
    }
    let files: Vec<String> = names.iter().map(|n| format!("{n}.mkt")).collect();
    let entries: Vec<(&str, &str)> =
        names.iter().map(String::as_str).zip(files.iter().map(String::as_str)).collect();
    let catalog = Catalog::describe(&entries, Some(dir), &CatalogOptions::default()).expect("describe");
    (catalog, pitch)
}

/// Boxes over none, one, two and four of the models, a thin slab over a
/// row, and everything.
fn regions(catalog: &Catalog, pitch: [f64; 2]) -> Vec<Region> {
    let first = catalog.models()[0].root_box.expect("a tree");
    let all = catalog.models().iter().filter_map(|m| m.root_box).fold(first, |a, b| a.union(&b));
    let (lo, hi) = (first.min, first.max);
    let mid = |a: usize| (lo[a] + hi[a]) / 2.0;
    vec![
        Region::Box(Aabb::from_array([lo.x - 1e6, lo.y - 1e6, lo.z, lo.x - 5e5, lo.y - 5e5, hi.z])),
        Region::Box(Aabb::from_array([lo.x, lo.y, lo.z, mid(0), mid(1), mid(2)])),
        Region::Box(Aabb::from_array([mid(0), lo.y, lo.z, mid(0) + pitch[0], hi.y, hi.z])),
        Region::Box(Aabb::from_array([mid(0), mid(1), lo.z, mid(0) + pitch[0], mid(1) + pitch[1], hi.z])),
        Region::Box(Aabb::from_array([all.min.x, mid(1), mid(2), all.max.x, mid(1) + 1.0, mid(2) + 1.0])),
        Region::Box(all),
    ]
}

/// Every (model, key) the files answer when each is queried on its own.
fn union_of_local_answers(dir: &Path, catalog: &Catalog, region: &Region) -> BTreeSet<(String, Key)> {
    let mut out = BTreeSet::new();
    for m in catalog.models() {
        let db = Database::open_read_only(dir.join(&m.location)).expect("open");
        let answer = mktree::query::query_region(
            &db.begin_read().expect("read"),
            region,
            &QueryOptions::default(),
            None,
        )
        .expect("query");
        out.extend(answer.keys.into_iter().map(|k| (m.key.clone(), k)));
    }
    out
}

#[test]
fn a_query_answers_the_union_of_the_files_and_opens_only_those_it_meets() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (catalog, pitch) = twenty_files(dir.path());
    catalog.write(dir.path().join("models.json")).expect("write");
    let read = Catalog::read(dir.path().join("models.json")).expect("read back");
    assert_eq!(read.models(), catalog.models());
    let met_counts: Vec<usize> = regions(&read, pitch)
        .iter()
        .map(|region| {
            // A fresh reader per region, so what it opened is this query's.
            let reader = read.clone().reader(CatalogOptions::default());
            let answer = reader.query(region, &QueryOptions::default()).expect("catalog query");
            let found: BTreeSet<(String, Key)> =
                answer.hits().map(|h| (h.model.to_string(), h.key.clone())).collect();
            assert_eq!(found.len(), answer.hits().count(), "a qualified key twice");
            assert_eq!(found, union_of_local_answers(dir.path(), &read, region), "{region:?}");
            assert_eq!(reader.opened(), answer.models.len());
            assert_eq!(answer.models.len() + answer.skipped, MODELS);
            assert_eq!(answer.models.iter().map(|m| m.model).collect::<Vec<_>>(), reader.models_met(region));
            answer.models.len()
        })
        .collect();
    assert_eq!(met_counts, [0, 1, 2, 4, 5, MODELS]);
}

#[test]
fn a_file_that_moved_on_from_the_catalog_is_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (catalog, _) = twenty_files(dir.path());
    let scene =
        generate_scene(&GenOptions { preset: Preset::Tanker1, objects: None, seed: 1 }).expect("preset");
    let db = Database::open(dir.path().join("m03.mkt")).expect("open to write");
    let mut w = db.begin_write().expect("write");
    w.bulk_load(&scene, &BuildParams::default(), &|_| {}).expect("bulk load");
    w.commit().expect("a later commit");
    drop(db);
    let reader = catalog.reader(CatalogOptions { concurrency: 1, ..CatalogOptions::default() });
    let everything = Region::Box(Aabb::from_array([-1e9, -1e9, -1e9, 1e9, 1e9, 1e9]));
    match reader.query(&everything, &QueryOptions::default()) {
        Err(CatalogError::Stale { model, catalog, file }) => {
            assert_eq!(model, "m03");
            assert!(file > catalog, "{file} after {catalog}");
        }
        other => panic!("expected a stale model, got {other:?}"),
    }
}

#[cfg(feature = "object-store")]
#[test]
fn over_http_only_the_files_a_query_meets_get_requests() {
    use common::servers::nginx;

    let Some(server) = nginx() else { return };
    let www = server.dir.path().join("www");
    let (local, pitch) = twenty_files(&www);
    let remote = Catalog::new(
        local
            .models()
            .iter()
            .map(|m| mktree::catalog::CatalogModel {
                location: format!("http://127.0.0.1:{}/{}", server.port, m.location),
                ..m.clone()
            })
            .collect(),
        None,
    )
    .expect("a catalog of URLs");
    for region in regions(&local, pitch) {
        let before = server.logged_requests().len();
        let reader = remote.clone().reader(CatalogOptions::default());
        let answer = reader.query(&region, &QueryOptions::default()).expect("catalog query over HTTP");
        let found: BTreeSet<(String, Key)> =
            answer.hits().map(|h| (h.model.to_string(), h.key.clone())).collect();
        assert_eq!(found, union_of_local_answers(&www, &local, &region), "{region:?}");
        let counted: u64 = answer.models.iter().map(|m| m.transfer.expect("remote counts").requests).sum();
        let logged = server.logged_requests_once(before + counted as usize);
        let requested: BTreeSet<String> = logged[before..]
            .iter()
            .filter_map(|line| local.models().iter().find(|m| line.contains(&format!("/{} ", m.location))))
            .map(|m| m.key.clone())
            .collect();
        let met: BTreeSet<String> = answer.models.iter().map(|m| m.key.clone()).collect();
        assert_eq!(requested, met, "{region:?}");
        assert_eq!(counted as usize, logged.len() - before, "{region:?}");
    }
}
