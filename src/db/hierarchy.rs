//! The stored tree read back as a [`Hierarchy`], so `stats` and `dump`
//! report a file exactly as they report a tree built in memory (boxes are the
//! stored f32 boxes, rounded outward; overlaps the stored f32 values).

use std::collections::HashMap;

use super::ReadTransaction;
use crate::build::{Hierarchy, Node, NodeId, NodeKind, Order, Split};
use crate::store::{ReadStats, StorageError};

/// Every node of the snapshot's tree, in preorder, with each leaf's objects
/// (this reads the whole tree, geometry included).
pub fn read_hierarchy(txn: &ReadTransaction) -> Result<Hierarchy, StorageError> {
    let mut ids: HashMap<(u32, u16), u32> = HashMap::new();
    let mut records = Vec::new();
    txn.walk_nodes(&mut ReadStats::default(), |at, rec| {
        if rec.node_id as usize != records.len() {
            return Err(StorageError::corrupt_record(
                at.block,
                u32::from(at.slot),
                "node_id",
                format!("{} is not preorder position {}", rec.node_id, records.len()),
            ));
        }
        ids.insert((at.block, at.slot), rec.node_id);
        records.push(rec.clone());
        Ok(())
    })?;
    let m = txn.pager().lod_levels() as usize;
    let mut nodes = Vec::with_capacity(records.len());
    for rec in records {
        let kind = match rec.children {
            Some((kids, s)) => NodeKind::Internal {
                children: kids.map(|c| NodeId(ids.get(&(c.block, c.slot)).copied().unwrap_or(u32::MAX))),
                split: Split {
                    axis: s.axis,
                    order: [Order::Min, Order::Max, Order::Center][usize::from(s.order.min(2))],
                    overlap: s.overlap.into(),
                    gap: s.gap.into(),
                },
            },
            None => {
                let mut objects: Vec<_> = txn
                    .read_objects(&rec.lods[m - 1][1], &mut ReadStats::default(), None)?
                    .into_iter()
                    .map(|(id, _)| id)
                    .collect();
                objects.sort_unstable();
                NodeKind::Leaf { objects }
            }
        };
        nodes.push(Node { aabb: rec.aabb(), level: rec.level.into(), kind });
    }
    Ok(Hierarchy { nodes })
}
