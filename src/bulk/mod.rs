//! Bulk loading: the MKtree hierarchy of §3 — MOA (MOA1/MOA2, §3.1), LAA
//! (LAA1-LAA3, §3.2), the median, Hilbert, SAH and volume-SAH reference
//! methods and `refine`, which refines the volume-SAH tree with MOA's cuts
//! under a cost model of box queries — and the paper's reports on it
//! (Tables 2-44).
//!
//! The builder works on object boxes (and, for the byte leaf rule, object
//! sizes), never on meshes. One algorithm per file: `cut.rs` is the step
//! MOA, LAA, LAA's trials and `refine` share, `cost.rs` the cost model,
//! `walk.rs` the depth-first engine under
//! every method, `driver.rs` the entry point.

mod cost;
mod cut;
mod driver;
mod error;
mod hierarchy;
mod hilbert;
mod laa;
mod leaf;
mod median;
mod moa;
mod params;
mod progress;
mod refine;
mod report;
mod sah;
mod splitter;
mod validate;
mod walk;

internal_use!(cost::{CostModel, MIX_SHARES, QueryMix});
pub use driver::build;
pub(crate) use driver::build_owned;
pub use error::BuildError;
pub(crate) use hierarchy::signed_intersection;
pub use hierarchy::{Hierarchy, Node, NodeId, NodeKind, Order, Preorder, Split};
internal_use!(hilbert::curve_order);
pub use leaf::{LeafRule, object_bytes};
pub use params::{BuildParams, LookAhead, Method, ParseParamError, QueryExtent, TieBreak};
pub(crate) use progress::StageMeter;
pub use progress::{BuildProgress, LoadProgress, Stage, TIME_LEFT_CHECKS, TimeLeft, TimeLeftCheck};
internal_use!(progress::estimate_work);
pub use report::{LevelRow, Report, TreeShape};
pub(crate) use validate::check_object_range;
pub use validate::{HierarchyError, check_range};
