//! Navigation (paper §1.5, on-line collision detection during a walk): a
//! sequence of frustum queries along a camera path, through one LRU buffer
//! pool of a fixed number of blocks kept from step to step, so a step reads
//! only what the previous steps' blocks do not hold; or (time-critical
//! rendering) the view's cut per step, through the same kind of pool.

use serde::Serialize;

use super::QueryError;
use super::select::Region;
use super::view::{View, ViewCut, ViewOptions};
use super::{QueryOptions, traverse};
use crate::geom::{Camera, Frustum, Point};
use crate::scene::ObjectId;
use crate::store::{BlockCache, ReadStats};
use crate::tree::ReadTransaction;

/// One step of a walk.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NavigateStep {
    /// The step's index in the path (0-based).
    pub step: usize,
    /// Sorted ids in view (exact at M, a superset below).
    pub objects: Vec<ObjectId>,
    /// Device reads by kind, and hits in the pool.
    pub reads: ReadStats,
    /// Wall time of the step, seconds.
    pub seconds: f64,
}

/// Frustum queries for `cameras` in order, with one pool of `cache_blocks`
/// blocks across the steps.
pub fn navigate(
    txn: &ReadTransaction,
    cameras: &[Camera],
    opts: &QueryOptions,
    cache_blocks: usize,
) -> Result<Vec<NavigateStep>, QueryError> {
    let cache = BlockCache::new(cache_blocks);
    cameras
        .iter()
        .enumerate()
        .map(|(step, camera)| {
            let region = Region::Frustum(Box::new(Frustum::from_camera(camera)?));
            let a = traverse(txn, &region, opts, Some(&cache))?;
            Ok(NavigateStep { step, objects: a.objects, reads: a.stats.reads, seconds: a.stats.seconds })
        })
        .collect()
}

/// The cut of each of `views` in order at `opts`' tolerance and budget (a
/// budget per step), with one pool of `cache_blocks` blocks across the steps.
pub fn navigate_view(
    txn: &ReadTransaction,
    views: &[View],
    opts: &ViewOptions,
    cache_blocks: usize,
) -> Result<Vec<ViewCut>, QueryError> {
    let cache = BlockCache::new(cache_blocks);
    views.iter().map(|v| txn.view(v, opts, Some(&cache))).collect()
}

/// A camera path: one `ex,ey,ez,tx,ty,tz` line (eye, target, mm) per step.
/// Blank lines and `#` comments are skipped, and so is a first line that
/// is not numbers (a header).
pub fn parse_path(text: &str) -> Result<Vec<(Point, Point)>, QueryError> {
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let bad = |detail: String| QueryError::Path { line: i + 1, detail };
        let fields: Result<Vec<f64>, _> = line.split(',').map(|f| f.trim().parse::<f64>()).collect();
        let v = match fields {
            Ok(v) => v,
            Err(_) if i == 0 && line.chars().any(|c| c.is_alphabetic()) => continue,
            Err(e) => return Err(bad(format!("{line:?}: {e}"))),
        };
        if v.len() != 6 || v.iter().any(|x| !x.is_finite()) {
            return Err(bad(format!("six finite numbers ex,ey,ez,tx,ty,tz expected, got {line:?}")));
        }
        out.push((Point::new(v[0], v[1], v[2]), Point::new(v[3], v[4], v[5])));
    }
    if out.is_empty() {
        return Err(QueryError::Path { line: 0, detail: "the path has no camera".into() });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_parse_with_a_header_and_refuse_bad_lines() {
        let p = parse_path("ex,ey,ez,tx,ty,tz\n0,0,0,1,0,0\n\n# x\n1,2,3, 4,5,6\n").unwrap();
        assert_eq!(p.len(), 2);
        assert_eq!(p[1].1, Point::new(4.0, 5.0, 6.0));
        assert!(matches!(parse_path("0,0,0,1,0\n"), Err(QueryError::Path { line: 1, .. })));
        assert!(matches!(parse_path("0,0,0,1,0,0\n0,0,x,1,0,0"), Err(QueryError::Path { line: 2, .. })));
        assert!(parse_path("0,0,0,1,0,inf\n").is_err());
        assert!(parse_path("").is_err());
    }
}
