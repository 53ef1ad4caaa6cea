//! What a walk that needs more than an answer (`check`, fetching a level,
//! clash, the view's cut) is shown as the one traversal meets records,
//! objects and stand-ins.

use std::sync::Arc;

use serde::Serialize;

use super::ObjectLevel;
use crate::geom::Aabb;
use crate::lod::Voxels;
use crate::scene::Mesh;
use crate::store::{Block, StorageError};

/// An object as the traversal met it: its box as stored, the bound that
/// decided it (or the finest it passed), its mesh when its geometry was
/// read, and the decision.
pub struct Seen<'a> {
    /// The id of the leaf holding it.
    pub leaf: u32,
    /// Its box as stored (of the part, for an object stored as parts).
    pub aabb: Aabb,
    /// The level and voxels of the bound that decided it, if one did.
    pub bound: Option<(u8, &'a Voxels)>,
    /// Its mesh, when its geometry was read.
    pub mesh: Option<&'a Mesh>,
    /// How it was decided.
    pub decision: ObjectLevel,
}

/// A node as a query that takes stand-ins may meet it before reading it:
/// its id when known without a read (a record read, a child in its
/// parent's block, or a first child, its parent's id + 1 while ids are
/// preorder numbers), its parent's id and which child it is (the root has
/// no parent).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct NodeName {
    /// The node's id; `None` when not known without a read.
    pub id: Option<u32>,
    /// The parent's id; `None` for the root.
    pub parent: Option<u32>,
    /// Which child of its parent it is (0 or 1; 0 for the root).
    pub child: u8,
}

/// Sees what a traversal meets: each record it enters (with the box its
/// parent holds for it) and each object it decides. Walks that need more
/// than an answer (`check`, fetching a level, clash) are visitors.
pub(crate) trait Visitor {
    /// Record `offset` of `block`, whose box is `frame`.
    fn node(&mut self, _block: &Arc<Block>, _offset: u32, _frame: &Aabb) -> Result<(), StorageError> {
        Ok(())
    }
    /// An object decided; with stand-ins, also an object settled or set
    /// aside at its bound's level, and each part of one that meets.
    fn object(&mut self, _seen: &Seen) -> Result<(), StorageError> {
        Ok(())
    }
    /// A query that takes stand-ins: node `name`, whose box is `frame`,
    /// stands in for its subtree (settled, or set aside by the budget).
    fn stand_in(&mut self, _name: &NodeName, _frame: &Aabb) -> Result<(), StorageError> {
        Ok(())
    }
    /// A query that takes stand-ins: node `name`'s group bound b(S_n,k),
    /// `voxels` within `eps` mm of its objects, stands in for its subtree.
    fn group(
        &mut self,
        _name: &NodeName,
        _frame: &Aabb,
        _level: u8,
        _voxels: &Voxels,
        _eps: f64,
    ) -> Result<(), StorageError> {
        Ok(())
    }
}

/// Sees nothing (plain queries).
impl Visitor for () {}
