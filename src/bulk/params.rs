//! Build options: the paper's arguments of `generate_tree` (MOA1 §3.1,
//! LAA1 §3.2) — `mem_page` (MemPage, in [`LeafRule`]), `rate` (R) and
//! `look_ahead_level` (LookAheadLevel) — plus the method and the rule that
//! breaks ties between equal-overlap cuts, and the query extent of the
//! cost model that `refine` minimises.

use std::fmt;
use std::str::FromStr;

use super::{BuildError, LeafRule};

/// Every option of a build. The default is the measured best
/// ([`BuildParams::for_blocks`] of 16 KiB); [`BuildParams::paper`] is the
/// paper's MOA with R = 0.2, `mem_page` = 100 objects, look-ahead 2 (for
/// LAA) and first-found tie-break.
#[derive(Debug, Clone, PartialEq)]
pub struct BuildParams {
    /// The splitting method.
    pub method: Method,
    /// `rate` (R), in [0, 0.5]: a cut leaves at least ⌊R·N⌋ objects on each
    /// side of a node of N objects (one more on the first side, as in
    /// MOA1). Higher values give shallower, more balanced trees with larger
    /// overlaps (§3.1.1). MOA and LAA only.
    pub rate: f64,
    /// When a node becomes a leaf: `mem_page` (MemPage) objects or a byte capacity.
    pub leaf: LeafRule,
    /// LAA only: how far the trial subtrees look below a node.
    pub look_ahead: LookAhead,
    /// MOA and LAA: which of several equally good cuts wins.
    pub tie_break: TieBreak,
    /// `refine`: the query extent q of the cost model it minimises
    /// (`bulk/cost.rs`).
    pub query_extent: QueryExtent,
}

/// The measured best (see [`BuildParams::for_blocks`]) for the default
/// 16 KiB blocks; a file of other blocks wants `for_blocks(its size)`.
impl Default for BuildParams {
    fn default() -> BuildParams {
        BuildParams::for_blocks(crate::store::format::DEFAULT_BLOCK_SIZE)
    }
}

impl BuildParams {
    /// The paper's setting: MOA, R 0.2, MemPage 100 objects (look-ahead 2
    /// levels when the method is LAA).
    pub fn paper() -> BuildParams {
        BuildParams {
            method: Method::Moa,
            rate: 0.2,
            leaf: LeafRule::Objects(100),
            look_ahead: LookAhead::Levels(2),
            tie_break: TieBreak::FirstFound,
            query_extent: QueryExtent::Auto,
        }
    }

    /// What `mktree build` uses for blocks of `block_size` bytes, and what
    /// the README measures as best: `refine` with R 0.2, and leaves whose
    /// geometry fills one geometry block.
    pub fn for_blocks(block_size: u32) -> BuildParams {
        BuildParams {
            method: Method::Refine,
            leaf: LeafRule::Bytes { capacity: crate::store::format::geometry::payload(block_size) },
            ..BuildParams::paper()
        }
    }

    /// Checks the options alone: R in [0, 0.5] and a non-zero capacity.
    pub fn validate(&self) -> Result<(), BuildError> {
        if !(0.0..=0.5).contains(&self.rate) {
            return Err(BuildError::RateOutOfRange { rate: self.rate });
        }
        if self.leaf.is_zero() {
            return Err(BuildError::ZeroCapacity);
        }
        if let QueryExtent::Mm(q) = self.query_extent
            && !q.iter().all(|x| x.is_finite() && *x >= 0.0)
        {
            return Err(BuildError::BadQueryExtent { query_extent: q });
        }
        Ok(())
    }
}

/// How a node's objects are divided in two.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Method {
    /// Minimum Overlap Algorithm (MOA1/MOA2, §3.1): the cut of least overlap
    /// over six sorted orders.
    Moa,
    /// Look Ahead Algorithm (LAA1-LAA3, §3.2): the candidate cut whose
    /// greedy trial subtrees accumulate the least overlap.
    Laa,
    /// Reference: halves at the median box centre along the node's longest axis.
    Median,
    /// Reference: halves of the run sorted once by the Hilbert code of box centres.
    Hilbert,
    /// Reference: the binned surface-area heuristic.
    Sah,
    /// The binned SAH with the volume of the boxes in place of their area.
    Vsah,
    /// `vsah`, then one top-down pass that replaces a node's cut by one of
    /// MOA's six candidates where that lowers the subtree's expected leaf
    /// accesses under the read model's cost model (`bulk/cost.rs`).
    Refine,
}

impl Method {
    /// Every method, in declaration order.
    pub const ALL: [Method; 7] = [
        Method::Moa,
        Method::Laa,
        Method::Median,
        Method::Hilbert,
        Method::Sah,
        Method::Vsah,
        Method::Refine,
    ];

    /// "moa", "laa", "median", "hilbert", "sah", "vsah" or "refine".
    pub fn name(self) -> &'static str {
        match self {
            Method::Moa => "moa",
            Method::Laa => "laa",
            Method::Median => "median",
            Method::Hilbert => "hilbert",
            Method::Sah => "sah",
            Method::Vsah => "vsah",
            Method::Refine => "refine",
        }
    }
}

/// The query extent q of the cost model: per axis, the side of the box
/// queries the tree is tuned for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum QueryExtent {
    /// Taken from the data: the mean extent of the objects' boxes on each
    /// axis plus 100 mm (a collision query about an object of the scene).
    Auto,
    /// Fixed sides, in mm, one per axis.
    Mm([f64; 3]),
}

/// How far LAA's trial subtrees look below the node being split.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum LookAhead {
    /// `look_ahead_level`: trial nodes up to this many levels below the
    /// node's children are split and their overlaps counted. `Levels(0)`
    /// counts the candidate's own overlap only: exactly MOA.
    Levels(u32),
    /// Trials run down to the leaves.
    Max,
}

impl LookAhead {
    /// The deepest trial level split, counting the candidate's children as
    /// level 1 (`u32::MAX` for `Max`: deeper than any tree).
    pub(crate) fn levels(self) -> u32 {
        match self {
            LookAhead::Levels(levels) => levels,
            LookAhead::Max => u32::MAX,
        }
    }
}

/// Which cut wins among cuts of equal overlap. The paper reports overlaps
/// clamped at zero (the length of the intersection), so every cut with a
/// gap ties at zero.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum TieBreak {
    /// The paper's rule (MOA2): the first cut found with a strictly smaller
    /// clamped overlap, in cut order and then in the six-order.
    FirstFound,
    /// The smallest raw value: among gaps, the widest.
    WidestGap,
    /// Among equal clamped overlaps, the cut nearest the middle of the node.
    MostBalanced,
}

impl TieBreak {
    /// Every rule, in declaration order.
    pub const ALL: [TieBreak; 3] = [TieBreak::FirstFound, TieBreak::WidestGap, TieBreak::MostBalanced];

    /// "first-found", "widest-gap" or "most-balanced".
    pub fn name(self) -> &'static str {
        match self {
            TieBreak::FirstFound => "first-found",
            TieBreak::WidestGap => "widest-gap",
            TieBreak::MostBalanced => "most-balanced",
        }
    }
}

/// A name that is not one of a parameter's values.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown {what} {value:?}: expected {expected}")]
pub struct ParseParamError {
    what: &'static str,
    value: String,
    expected: &'static str,
}

/// The value among `all` whose name is `s`.
fn parse_named<T: Copy>(
    s: &str,
    all: &[T],
    name: fn(T) -> &'static str,
    what: &'static str,
    expected: &'static str,
) -> Result<T, ParseParamError> {
    all.iter().copied().find(|&v| name(v) == s).ok_or_else(|| ParseParamError {
        what,
        value: s.to_owned(),
        expected,
    })
}

impl FromStr for Method {
    type Err = ParseParamError;
    fn from_str(s: &str) -> Result<Method, ParseParamError> {
        parse_named(s, &Method::ALL, Method::name, "method", "moa, laa, median, hilbert, sah, vsah or refine")
    }
}

impl FromStr for TieBreak {
    type Err = ParseParamError;
    fn from_str(s: &str) -> Result<TieBreak, ParseParamError> {
        parse_named(
            s,
            &TieBreak::ALL,
            TieBreak::name,
            "tie-break",
            "first-found, widest-gap or most-balanced",
        )
    }
}

impl FromStr for LookAhead {
    type Err = ParseParamError;
    fn from_str(s: &str) -> Result<LookAhead, ParseParamError> {
        match s {
            "max" => Ok(LookAhead::Max),
            _ => s.parse().map(LookAhead::Levels).map_err(|_| ParseParamError {
                what: "look-ahead",
                value: s.to_owned(),
                expected: "a number of levels or max",
            }),
        }
    }
}

impl fmt::Display for Method {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl fmt::Display for TieBreak {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for QueryExtent {
    type Err = ParseParamError;
    /// `auto`, one side in mm for all three axes, or three comma-separated sides.
    fn from_str(s: &str) -> Result<QueryExtent, ParseParamError> {
        if s == "auto" {
            return Ok(QueryExtent::Auto);
        }
        let bad = || ParseParamError {
            what: "query extent",
            value: s.to_owned(),
            expected: "auto, a side in mm, or three sides x,y,z (finite, >= 0)",
        };
        let v: Vec<f64> =
            s.split(',').map(|x| x.trim().parse::<f64>()).collect::<Result<_, _>>().map_err(|_| bad())?;
        let q = match v[..] {
            [a] => [a; 3],
            [a, b, c] => [a, b, c],
            _ => return Err(bad()),
        };
        if q.iter().all(|x| x.is_finite() && *x >= 0.0) { Ok(QueryExtent::Mm(q)) } else { Err(bad()) }
    }
}

impl fmt::Display for QueryExtent {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            QueryExtent::Auto => f.write_str("auto"),
            QueryExtent::Mm([a, b, c]) if a == b && b == c => write!(f, "{a}"),
            QueryExtent::Mm([a, b, c]) => write!(f, "{a},{b},{c}"),
        }
    }
}

impl fmt::Display for LookAhead {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LookAhead::Levels(levels) => levels.fmt(f),
            LookAhead::Max => f.write_str("max"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_parse_back() {
        for m in Method::ALL {
            assert_eq!(m.name().parse::<Method>(), Ok(m));
        }
        for t in TieBreak::ALL {
            assert_eq!(t.to_string().parse::<TieBreak>(), Ok(t));
        }
        for l in [LookAhead::Levels(0), LookAhead::Levels(7), LookAhead::Max] {
            assert_eq!(l.to_string().parse::<LookAhead>(), Ok(l));
        }
        for q in [QueryExtent::Auto, QueryExtent::Mm([150.0; 3]), QueryExtent::Mm([1.0, 2.5, 0.0])] {
            assert_eq!(q.to_string().parse::<QueryExtent>(), Ok(q));
        }
        for bad in ["", "1,2", "-1", "nan", "1,2,inf", "x"] {
            assert!(bad.parse::<QueryExtent>().is_err(), "{bad}");
        }
        assert!("rtree".parse::<Method>().is_err());
        assert!("-1".parse::<LookAhead>().is_err());
    }

    #[test]
    fn rates_outside_the_closed_half_interval_are_refused() {
        for rate in [-0.01, 0.51, f64::NAN, f64::INFINITY] {
            let p = BuildParams { rate, ..BuildParams::paper() };
            assert!(matches!(p.validate(), Err(BuildError::RateOutOfRange { .. })), "{rate}");
        }
        for rate in [0.0, 0.5] {
            assert_eq!(BuildParams { rate, ..BuildParams::paper() }.validate(), Ok(()));
        }
    }
}
