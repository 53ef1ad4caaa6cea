//! Grouping clashes (docs/clash.md, "Groups"), as Navisworks' folders do:
//! by proximity (contact points within g mm of one another, linked in
//! chains: single linkage), by the A object, or by the first n characters
//! of the A key. Groups come in the order of their first clash.

use std::collections::HashMap;
use std::fmt;
use std::str::FromStr;

use serde::Serialize;

use super::ClashError;
use super::key_json::{key_text, write_key_text};
use super::test::Clash;
use crate::geom::{Aabb, Point};

/// How clashes are grouped.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum GroupBy {
    /// Each clash its own group.
    #[default]
    None,
    /// Contact points within this many mm, linked in chains.
    Proximity(f64),
    /// One group per A object.
    ObjectA,
    /// One group per first n characters of the A key.
    KeyPrefix(usize),
}

impl FromStr for GroupBy {
    type Err = ClashError;

    /// `none`, `proximity:G` (mm), `a`, `prefix:N`.
    fn from_str(s: &str) -> Result<GroupBy, ClashError> {
        let bad = || ClashError::Test(format!("grouping {s:?}: expected none, a, proximity:MM or prefix:N"));
        Ok(match s.split_once(':') {
            None if s == "none" => GroupBy::None,
            None if s == "a" => GroupBy::ObjectA,
            Some(("proximity", g)) => {
                let g: f64 = g.parse().map_err(|_| bad())?;
                if !(g.is_finite() && (0.0..=super::test::MAX_DISTANCE).contains(&g)) {
                    return Err(bad());
                }
                GroupBy::Proximity(g)
            }
            Some(("prefix", n)) => GroupBy::KeyPrefix(n.parse().map_err(|_| bad())?),
            _ => return Err(bad()),
        })
    }
}

impl fmt::Display for GroupBy {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            GroupBy::None => f.write_str("none"),
            GroupBy::Proximity(g) => write!(f, "proximity:{g}"),
            GroupBy::ObjectA => f.write_str("a"),
            GroupBy::KeyPrefix(n) => write!(f, "prefix:{n}"),
        }
    }
}

/// A group of clashes.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Group {
    /// Its number, from 0 in the order of first clashes.
    pub id: usize,
    /// A name a person reads: the A key, the prefix, or where it is.
    pub name: String,
    /// Its clashes, as indices into the run's list, increasing.
    pub members: Vec<usize>,
    /// The box of its clashes' contact points and boxes' overlap.
    #[serde(serialize_with = "box_array")]
    pub aabb: Aabb,
    /// The centre of its contact points.
    #[serde(serialize_with = "point_array")]
    pub point: Point,
}

fn box_array<S: serde::Serializer>(b: &Aabb, s: S) -> Result<S::Ok, S::Error> {
    serde::Serialize::serialize(&b.to_array(), s)
}

fn point_array<S: serde::Serializer>(p: &Point, s: S) -> Result<S::Ok, S::Error> {
    serde::Serialize::serialize(&[p.x, p.y, p.z], s)
}

/// Groups `clashes` (clashes, or a recorded run's tracked clashes) by `by`.
pub fn group<C: AsRef<Clash>>(clashes: &[C], by: GroupBy) -> Vec<Group> {
    if by == GroupBy::None {
        // A group per clash, made in one pass: a run on 10^6 objects makes
        // 1.5 million, and labelling them was a sixth of its re-run.
        return clashes.iter().map(AsRef::as_ref).enumerate().map(|(i, c)| alone(i, c)).collect();
    }
    let ids = group_ids(clashes, by);
    let count = ids.iter().max().map_or(0, |&m| m + 1);
    let mut groups: Vec<Group> = (0..count)
        .map(|id| Group {
            id,
            name: String::new(),
            members: Vec::new(),
            aabb: Aabb::EMPTY,
            point: Point::origin(),
        })
        .collect();
    for (i, (c, &id)) in clashes.iter().map(AsRef::as_ref).zip(&ids).enumerate() {
        let g = &mut groups[id];
        g.members.push(i);
        g.aabb = g.aabb.including(&c.point).union(&c.overlap.unwrap_or(Aabb::new(c.point, c.point)));
    }
    for g in &mut groups {
        let sum =
            g.members.iter().fold(nalgebra::Vector3::zeros(), |s, &i| s + clashes[i].as_ref().point.coords);
        g.point = Point::from(sum / g.members.len() as f64);
        let first = clashes[g.members[0]].as_ref();
        g.name = match by {
            GroupBy::ObjectA => key_text(&first.a),
            GroupBy::KeyPrefix(n) => format!("{}*", key_text(&first.a).chars().take(n).collect::<String>()),
            GroupBy::None => pair_name(first),
            GroupBy::Proximity(_) => {
                format!(
                    "{} clashes near ({:.0}, {:.0}, {:.0})",
                    g.members.len(),
                    g.point.x,
                    g.point.y,
                    g.point.z
                )
            }
        };
    }
    groups
}

/// The group of each of `clashes` by `by`, numbered as [`group`] numbers
/// them (from 0, in the order of their first clashes), without making the
/// groups: what a table of the clashes needs.
pub fn group_ids<C: AsRef<Clash>>(clashes: &[C], by: GroupBy) -> Vec<usize> {
    // Each label is the index of its group's first clash.
    let label: Vec<usize> = match by {
        GroupBy::None => return (0..clashes.len()).collect(),
        GroupBy::ObjectA => first_of(clashes.iter().map(|c| key_text(&c.as_ref().a))),
        GroupBy::KeyPrefix(n) => {
            first_of(clashes.iter().map(|c| key_text(&c.as_ref().a).chars().take(n).collect()))
        }
        GroupBy::Proximity(g) => proximity(clashes, g),
    };
    // Labels are clash indices, so a group's number is found by indexing,
    // not hashing.
    let mut at = vec![usize::MAX; clashes.len()];
    let mut next = 0;
    label
        .iter()
        .map(|&l| {
            if at[l] == usize::MAX {
                at[l] = next;
                next += 1;
            }
            at[l]
        })
        .collect()
}

/// The group of clash `i` alone: what the general pass makes of it.
fn alone(i: usize, c: &Clash) -> Group {
    Group {
        id: i,
        name: pair_name(c),
        members: vec![i],
        aabb: Aabb::EMPTY.including(&c.point).union(&c.overlap.unwrap_or(Aabb::new(c.point, c.point))),
        point: c.point,
    }
}

/// A one-clash group's name: its two keys.
fn pair_name(c: &Clash) -> String {
    let mut name = String::new();
    write_key_text(&mut name, &c.a);
    name.push_str(" / ");
    write_key_text(&mut name, &c.b);
    name
}

/// For each item, the index of the first item with the same label.
fn first_of(labels: impl Iterator<Item = String>) -> Vec<usize> {
    let mut first: HashMap<String, usize> = HashMap::new();
    labels.enumerate().map(|(i, l)| *first.entry(l).or_insert(i)).collect()
}

/// Single linkage of contact points within `g`: for each clash, the least
/// index in its chain. Points are hashed to cells of side g, so each is
/// compared with the points of its 27 neighbouring cells.
fn proximity<C: AsRef<Clash>>(clashes: &[C], g: f64) -> Vec<usize> {
    let mut parent: Vec<usize> = (0..clashes.len()).collect();
    fn root(p: &mut [usize], mut i: usize) -> usize {
        while p[i] != i {
            p[i] = p[p[i]];
            i = p[i];
        }
        i
    }
    let cell = |p: &Point| -> [i64; 3] {
        let s = if g > 0.0 { g } else { 1.0 };
        [p.x, p.y, p.z].map(|x| (x / s).floor().clamp(-1e15, 1e15) as i64)
    };
    let mut cells: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
    for (i, c) in clashes.iter().map(AsRef::as_ref).enumerate() {
        cells.entry(cell(&c.point)).or_default().push(i);
    }
    for (i, c) in clashes.iter().map(AsRef::as_ref).enumerate() {
        let k = cell(&c.point);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let Some(near) = cells.get(&[k[0] + dx, k[1] + dy, k[2] + dz]) else { continue };
                    for &j in near {
                        if j < i && (clashes[j].as_ref().point - c.point).norm() <= g {
                            let (ri, rj) = (root(&mut parent, i), root(&mut parent, j));
                            let (lo, hi) = (ri.min(rj), ri.max(rj));
                            parent[hi] = lo;
                        }
                    }
                }
            }
        }
    }
    (0..clashes.len()).map(|i| root(&mut parent, i)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn at(a: u64, x: f64) -> Clash {
        let p = Point::new(x, 0.0, 0.0);
        Clash::hard_at(a, 100 + a, p)
    }

    #[test]
    fn proximity_links_chains_and_keeps_far_points_apart() {
        let cs = [at(1, 0.0), at(2, 40.0), at(3, 80.0), at(4, 500.0), at(1, 505.0)];
        let g = group(&cs, GroupBy::Proximity(50.0));
        assert_eq!(g.iter().map(|g| g.members.clone()).collect::<Vec<_>>(), vec![vec![0, 1, 2], vec![3, 4]]);
        let g = group(&cs, GroupBy::ObjectA);
        assert_eq!(
            g.iter().map(|g| g.members.clone()).collect::<Vec<_>>(),
            vec![vec![0, 4], vec![1], vec![2], vec![3]]
        );
        assert_eq!(group(&cs, GroupBy::None).len(), 5);
        assert_eq!("proximity:50".parse::<GroupBy>().unwrap(), GroupBy::Proximity(50.0));
        assert!("proximity:-1".parse::<GroupBy>().is_err() && "near".parse::<GroupBy>().is_err());
    }

    #[test]
    fn a_group_per_clash_is_named_boxed_and_placed_as_its_clash() {
        let mut cs = [at(1, 0.0), at(2, 40.0)];
        cs[1].overlap = Some(Aabb::from_array([30.0, -1.0, -1.0, 45.0, 1.0, 1.0]));
        let g = group(&cs, GroupBy::None);
        assert_eq!(
            g.iter().map(|g| (g.id, g.members.clone())).collect::<Vec<_>>(),
            vec![(0, vec![0]), (1, vec![1])]
        );
        assert_eq!((g[0].name.as_str(), g[1].name.as_str()), ("1 / 101", "2 / 102"));
        assert_eq!(g[0].aabb, Aabb::new(cs[0].point, cs[0].point));
        assert_eq!(g[1].aabb, Aabb::from_array([30.0, -1.0, -1.0, 45.0, 1.0, 1.0]));
        assert_eq!((g[0].point, g[1].point), (cs[0].point, cs[1].point));
    }

    proptest! {
        /// `group_ids` numbers each clash's group as `group` does, by every
        /// grouping.
        #[test]
        fn group_ids_are_the_groups_numbers(
            xs in prop::collection::vec((0u32..2000, 0u64..6), 0..40), g in 1u32..200,
        ) {
            let cs: Vec<Clash> = xs.iter().map(|&(x, a)| at(a * 11, f64::from(x))).collect();
            for by in [GroupBy::None, GroupBy::ObjectA, GroupBy::KeyPrefix(1), GroupBy::Proximity(f64::from(g))] {
                let ids = group_ids(&cs, by);
                let groups = group(&cs, by);
                prop_assert_eq!(ids.len(), cs.len());
                for gr in &groups {
                    for &m in &gr.members {
                        prop_assert_eq!(ids[m], gr.id);
                    }
                }
            }
        }

        /// Every clash is in exactly one group; points of one group are
        /// linked by steps of at most g, and points of different groups are
        /// more than g apart.
        #[test]
        fn proximity_groups_partition_by_chains(xs in prop::collection::vec(0u32..2000, 0..40), g in 1u32..200) {
            let cs: Vec<Clash> = xs.iter().enumerate().map(|(i, &x)| at(i as u64, f64::from(x))).collect();
            let g = f64::from(g);
            let groups = group(&cs, GroupBy::Proximity(g));
            let mut seen = vec![0; cs.len()];
            for gr in &groups {
                for &m in &gr.members { seen[m] += 1; }
            }
            prop_assert!(seen.iter().all(|&n| n == 1));
            for (a, ga) in groups.iter().enumerate() {
                for gb in &groups[a + 1..] {
                    for &i in &ga.members {
                        for &j in &gb.members {
                            prop_assert!((cs[i].point - cs[j].point).norm() > g);
                        }
                    }
                }
            }
        }
    }
}
