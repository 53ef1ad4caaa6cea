//! The leaf rule: the paper's `InPage(S_n)` (§1.2, used by MOA1, LAA1 and
//! LAA3), and the one estimate of an object's stored size that it may use.
//!
//! A node is a leaf when its objects fit one page: by count (`mem_page`
//! (MemPage) objects, as in the paper's tables) or by bytes (the encoded
//! exact geometry fits one block). A single object is always a leaf, even
//! when it is bigger than a block: it cannot be divided further.
//!
//! [`object_bytes`] stands in for the storage layer's encoding until that
//! layer defines it; this file is the one place to replace.

use super::BuildError;
use crate::scene::Mesh;

/// When a node stops splitting and becomes a leaf.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LeafRule {
    /// `mem_page` (MemPage): at most this many objects per leaf. Smaller
    /// pages give deeper trees with more, smaller leaves (§3.1.1).
    Objects(u32),
    /// The sum of the objects' sizes (see [`object_bytes`]) is at most
    /// `capacity` bytes: a block of that size holds the leaf's geometry.
    Bytes {
        /// Block capacity in bytes.
        capacity: u64,
    },
}

impl LeafRule {
    /// True when the rule admits nothing (0 objects or 0 bytes).
    pub fn is_zero(&self) -> bool {
        match *self {
            LeafRule::Objects(mem_page) => mem_page == 0,
            LeafRule::Bytes { capacity } => capacity == 0,
        }
    }

    /// About how many objects a full leaf holds: `mem_page`, or the
    /// capacity over the mean object size (one object per leaf when the
    /// sizes are unknown, the pessimistic case). At least 1.
    pub(crate) fn objects_per_leaf(&self, sizes: Option<&[u64]>) -> f64 {
        match *self {
            LeafRule::Objects(mem_page) => f64::from(mem_page).max(1.0),
            LeafRule::Bytes { capacity } => match sizes {
                Some(s) if !s.is_empty() => {
                    let mean = s.iter().map(|&b| b as f64).sum::<f64>() / s.len() as f64;
                    if mean > 0.0 { (capacity as f64 / mean).max(1.0) } else { f64::INFINITY }
                }
                _ => 1.0,
            },
        }
    }
}

/// Header bytes of one stored object: id (4), vertex and triangle counts
/// (4 + 4), padding (4) and the f64 anchor (24).
const OBJECT_HEADER_BYTES: u64 = 40;
/// Bytes per vertex: an f32 offset per axis.
const VERTEX_BYTES: u64 = 12;
/// Bytes per triangle: three u32 vertex indices.
const TRIANGLE_BYTES: u64 = 12;

/// An honest estimate of one object's encoded exact geometry, in bytes:
/// 40 bytes of header (id, counts, f64 anchor) + 12 per vertex (f32 xyz
/// offsets) + 12 per triangle (u32 x3). Replaced by the storage layer's
/// encoding once it exists.
///
/// ```
/// # use mktree::geom::Point;
/// # use mktree::scene::Mesh;
/// let p = [Point::new(0.0, 0.0, 0.0), Point::new(1.0, 0.0, 0.0), Point::new(0.0, 1.0, 0.0)];
/// let mesh = Mesh::from_world(&p, vec![[0, 1, 2]])?;
/// assert_eq!(mktree::bulk::object_bytes(&mesh), 40 + 3 * 12 + 12);
/// # Ok::<(), mktree::scene::MeshError>(())
/// ```
pub fn object_bytes(mesh: &Mesh) -> u64 {
    OBJECT_HEADER_BYTES
        + VERTEX_BYTES * mesh.vertex_count() as u64
        + TRIANGLE_BYTES * mesh.triangle_count() as u64
}

/// A [`LeafRule`] joined with the sizes it needs: the `InPage` test.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Leaf<'a> {
    Objects(usize),
    Bytes { capacity: u64, sizes: &'a [u64] },
}

impl<'a> Leaf<'a> {
    /// The test for `rule`; `sizes` must already have one entry per object.
    pub(crate) fn new(rule: LeafRule, sizes: Option<&'a [u64]>) -> Result<Leaf<'a>, BuildError> {
        match rule {
            LeafRule::Objects(mem_page) => Ok(Leaf::Objects(mem_page as usize)),
            LeafRule::Bytes { capacity } => {
                sizes.map(|sizes| Leaf::Bytes { capacity, sizes }).ok_or(BuildError::MissingSizes)
            }
        }
    }

    /// `InPage(S_n)`: the objects fit one page, or there is only one.
    pub(crate) fn fits(&self, objects: &[u32]) -> bool {
        if objects.len() <= 1 {
            return true;
        }
        match *self {
            Leaf::Objects(mem_page) => objects.len() <= mem_page,
            // Stops at the first object past the capacity: asked of every
            // node of every trial, most of them far bigger than a page.
            Leaf::Bytes { capacity, sizes } => objects
                .iter()
                .try_fold(0u64, |sum, &j| {
                    Some(sum.saturating_add(sizes[j as usize])).filter(|&s| s <= capacity)
                })
                .is_some(),
        }
    }

    /// What the rule counts: objects, or their total bytes (saturating).
    pub(crate) fn measure(&self, objects: &[u32]) -> u64 {
        match *self {
            Leaf::Objects(_) => objects.len() as u64,
            // `sizes` has one entry per object: checked before any build.
            Leaf::Bytes { sizes, .. } => {
                objects.iter().fold(0u64, |sum, &j| sum.saturating_add(sizes[j as usize]))
            }
        }
    }

    /// The most [`Leaf::measure`] a page holds.
    pub(crate) fn limit(&self) -> u64 {
        match *self {
            Leaf::Objects(mem_page) => mem_page as u64,
            Leaf::Bytes { capacity, .. } => capacity,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_single_object_fits_even_when_bigger_than_a_page() {
        let sizes = [1_000, 10, 10];
        let leaf = Leaf::new(LeafRule::Bytes { capacity: 100 }, Some(&sizes)).unwrap();
        assert!(leaf.fits(&[0]));
        assert!(!leaf.fits(&[0, 1]));
        assert!(leaf.fits(&[1, 2]));
        assert!(Leaf::Objects(1).fits(&[7]));
        assert!(!Leaf::Objects(1).fits(&[7, 8]));
    }

    proptest::proptest! {
        #[test]
        fn a_set_fits_when_its_measure_is_within_the_limit(
            sizes in proptest::collection::vec(0u64..u64::MAX / 2, 1..40),
            capacity in 0u64..u64::MAX,
            pick in proptest::collection::vec(0usize..40, 0..12),
        ) {
            let leaf = Leaf::Bytes { capacity, sizes: &sizes };
            let objects: Vec<u32> = pick.iter().map(|&i| (i % sizes.len()) as u32).collect();
            let expected = objects.len() <= 1 || leaf.measure(&objects) <= leaf.limit();
            proptest::prop_assert_eq!(leaf.fits(&objects), expected);
        }
    }

    #[test]
    fn the_byte_rule_without_sizes_is_refused() {
        assert!(matches!(Leaf::new(LeafRule::Bytes { capacity: 1 }, None), Err(BuildError::MissingSizes)));
    }
}
