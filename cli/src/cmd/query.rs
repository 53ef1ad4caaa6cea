//! `mktree query`: a box, sphere or frustum query at level k through the
//! file, with its block reads; also the JSON and text every single-shape
//! query prints (collide uses them).

use std::path::Path;

use anyhow::{Result, bail};
use mktree::geom::{Aabb, Camera, Frustum, Point, Sphere};
use mktree::query::{QueryOptions, Region, query_region};

use crate::args::ShapeArgs;
use crate::output;

/// The region the flags name (clap lets exactly one through).
pub fn shape(shape: &ShapeArgs) -> Result<Region> {
    Ok(match (shape.aabb, shape.sphere, shape.frustum) {
        (Some(b), _, _) => Region::Box(Aabb::from_array(b)),
        (_, Some(s), _) => Region::Sphere(Sphere::new(Point::new(s[0], s[1], s[2]), s[3])?),
        (_, _, Some(f)) => Region::Frustum(Box::new(Frustum::from_camera(&Camera {
            eye: Point::new(f[0], f[1], f[2]),
            target: Point::new(f[3], f[4], f[5]),
            fov_deg: f[6],
            aspect: f[7],
            near: f[8],
            far: f[9],
        })?)),
        _ => bail!("one of --box, --sphere, --frustum is needed"),
    })
}

pub fn run(file: &Path, region: &Region, opts: &QueryOptions, as_json: bool) -> Result<()> {
    let db = crate::input::open_to_read(file)?;
    let r = db.begin_read()?;
    let opened = db.transfer_counts();
    let answer = query_region(&r, region, opts, None)?;
    // A file in object storage: what opening it and what the query fetched.
    let Some((open, all)) = opened.zip(db.transfer_counts()) else {
        return output::print_answer(&answer, as_json);
    };
    let query = all.since(&open);
    if as_json {
        let mut value = output::answer_json(&answer);
        value["transfer"] = serde_json::json!({ "open": open, "query": query });
        return output::json(&value);
    }
    output::print_answer(&answer, false)?;
    println!("{}", output::transfer_line("open", &open));
    println!("{}", output::transfer_line("query", &query));
    Ok(())
}
