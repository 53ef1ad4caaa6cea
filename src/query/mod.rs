//! Queries through the paged file. Every query runs the one traversal of
//! `traverse/`, the [`Select`] iterator, with a [`Selection`]
//! (`select.rs`): region queries, the posed-mesh collide, clash (the tree
//! against itself, one probe per object), navigation, the speed-accuracy
//! trade-off, the view's cut through the levels of detail, and the walks
//! of `check`; or best first, ordered by a
//! distance (`rank.rs`): the nearest objects to a point, the hits along a
//! ray. Each returns its answer and the blocks it read, counted by the
//! pager where the reads happen.

mod answer;
mod batch;
#[cfg(feature = "internals")]
mod brute_force;
mod clash;
mod collide;
mod error;
mod navigate;
mod nearest;
mod range;
mod rank;
mod ray;
#[cfg(feature = "internals")]
mod records;
mod region;
mod select;
mod tradeoff;
mod traverse;
mod view;
mod visit;

pub(crate) use answer::levels;
pub use answer::{Hit, ObjectLevel, Proof, QueryAnswer, QueryOptions, TraverseStats};
pub use batch::{Request, Response, answer_request};
#[cfg(feature = "internals")]
pub use brute_force::{
    ScanOracle, brute_force_clash, brute_force_collide, brute_force_nearest, brute_force_ray,
    brute_force_region,
};
pub use clash::{ClashAnswer, ClashOptions, clash};
// For BCF snapshots, the one user outside this module.
#[cfg(feature = "bcf")]
pub(crate) use collide::fetch_meshes;
pub use collide::{CollideOptions, collide, object_mesh, object_meshes};
pub use error::QueryError;
pub use navigate::{NavigateStep, navigate, navigate_view, parse_path};
pub use nearest::{Near, Nearest};
pub use range::MAX_LENGTH;
pub use ray::{RayHit, RayHits};
#[cfg(feature = "internals")]
pub use records::{RecordAt, node_records};
pub use region::query_region;
pub use select::{Everything, Region, Selection, Triangles};
pub use tradeoff::{
    LevelBenefit, TRADEOFF_SHIFT_MM, TradeoffRow, collision_workload, level_benefit, tradeoff,
};
pub use traverse::{Select, traverse};
pub(crate) use traverse::{walk, walk_level};
pub use visit::NodeName;
internal_use!(visit::Seen);
pub use view::{Bound, CutNode, Shape, Shown, View, ViewCut, ViewOptions};
pub(crate) use visit::Visitor;
