//! `mktree gen` and `mktree info`.

use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

use anyhow::{Context, Result};
use mktree::scene::SceneInfo;
use mktree::scene::generate::{GenOptions, write_scene_obj};
use mktree::scene::import::ImportOptions;

use crate::output;

pub fn generate(preset: &str, objects: Option<u64>, seed: u64, out: &Path) -> Result<()> {
    let options = GenOptions { preset: preset.parse()?, objects, seed };
    let file = File::create(out).with_context(|| format!("creating {}", out.display()))?;
    let s = write_scene_obj(&options, BufWriter::new(file))?;
    let e = s.aabb.extent();
    eprintln!(
        "{}: {} objects, {} triangles, {} vertices, extent {:.0} x {:.0} x {:.0} mm",
        out.display(),
        s.objects,
        s.triangles,
        s.vertices,
        e.x,
        e.y,
        e.z
    );
    Ok(())
}

pub fn info(path: &Path, options: &ImportOptions, json: bool) -> Result<()> {
    let scene = crate::input::read_scene(path, options)?;
    let i = SceneInfo::of(&scene);
    if json {
        return output::json(&i);
    }
    println!("scene      {}", path.display());
    println!("objects    {}", i.objects);
    println!("triangles  {}", i.triangles);
    println!("vertices   {}", i.vertices);
    println!("extent     {:.3} x {:.3} x {:.3} mm", i.extent[0], i.extent[1], i.extent[2]);
    println!("bbox       [{}]", i.bbox.map(|x| format!("{x:.3}")).join(", "));
    let d = |name: &str, d: &mktree::scene::Distribution| {
        println!("{name:<30} min {:>10.3}  median {:>10.3}  max {:>10.3}", d.min, d.median, d.max);
    };
    d("triangles per object", &i.triangles_per_object);
    d("object box longest side (mm)", &i.box_longest_side);
    d("object box shortest side (mm)", &i.box_shortest_side);
    if i.degenerate_triangles > 0 {
        println!("zero-area triangles {}", i.degenerate_triangles);
    }
    Ok(())
}
