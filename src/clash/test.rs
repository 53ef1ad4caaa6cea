//! A clash test and what it finds (docs/clash.md, "Tests" and "Results"):
//! the sets A and B, the type with its tolerance or distance, and each
//! clash with both keys, its type, depth or distance, contact point and
//! boxes.

use serde::{Deserialize, Serialize};

use super::ClashError;
use super::select::Selector;
use crate::geom::{Aabb, Point};
use crate::scene::Key;

/// The longest test name, bytes.
pub const MAX_NAME: usize = 255;

/// What a test looks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TestKind {
    /// Meshes that intersect, penetrating more than the tolerance.
    Hard,
    /// Meshes closer than the distance: hard clashes, and pairs apart by
    /// less than the distance.
    Clearance,
    /// The same geometry within the tolerance.
    Duplicate,
}

/// The type of one clash.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ClashKind {
    /// Intersecting, with a penetration above the tolerance.
    Hard,
    /// Apart, closer than the test's distance.
    Clearance,
    /// In contact with no penetration above the tolerance (a face, edge or
    /// point in common); reported only when the test asks.
    Touch,
    /// The same geometry within the tolerance.
    Duplicate,
}

impl ClashKind {
    /// The lowercase name, as JSON and the table show it.
    pub fn name(self) -> &'static str {
        match self {
            ClashKind::Hard => "hard",
            ClashKind::Clearance => "clearance",
            ClashKind::Touch => "touch",
            ClashKind::Duplicate => "duplicate",
        }
    }
}

/// A clash test: two sets and a type.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ClashTest {
    /// Set A: the union of these selectors (empty: every object).
    pub a: Vec<Selector>,
    /// Set B; `None`: A against itself.
    pub b: Option<Vec<Selector>>,
    /// What the test looks for.
    pub kind: TestKind,
    /// mm: a hard clash penetrates more than this (less is a touch); a
    /// duplicate differs by at most this.
    pub tolerance: f64,
    /// mm: a clearance test reports pairs closer than this (strictly).
    pub distance: f64,
    /// Report touches (contact without penetration) too.
    pub touch: bool,
}

impl Default for ClashTest {
    fn default() -> ClashTest {
        ClashTest {
            a: Vec::new(),
            b: None,
            kind: TestKind::Hard,
            tolerance: DEFAULT_TOLERANCE,
            distance: 0.0,
            touch: false,
        }
    }
}

/// The default tolerance, mm: contacts whose intersection is thinner are
/// touches (floating-point crossings of coplanar faces are thinner by far).
pub const DEFAULT_TOLERANCE: f64 = 0.01;

/// The largest tolerance or distance a test takes, mm (2^40: far past
/// any model, and no grown box leaves the coordinate range).
pub const MAX_DISTANCE: f64 = 1_099_511_627_776.0;

impl ClashTest {
    /// Checks the numbers: finite, at least 0, at most [`MAX_DISTANCE`];
    /// a clearance test has a distance above 0.
    pub fn validate(&self) -> Result<(), ClashError> {
        for (what, x) in [("tolerance", self.tolerance), ("distance", self.distance)] {
            if !(x.is_finite() && (0.0..=MAX_DISTANCE).contains(&x)) {
                return Err(ClashError::Test(format!("{what} {x} is not a distance in [0, 2^40] mm")));
            }
        }
        if self.kind == TestKind::Clearance && self.distance <= 0.0 {
            return Err(ClashError::Test("a clearance test needs a distance above 0".into()));
        }
        Ok(())
    }

    /// How far apart two boxes may be and still hold a clash of this test.
    pub fn reach(&self) -> f64 {
        match self.kind {
            TestKind::Hard => 0.0,
            TestKind::Clearance => self.distance,
            TestKind::Duplicate => self.tolerance,
        }
    }
}

/// One clash: a pair of objects, a from set A and b from set B (when both
/// lie in both sets, a has the smaller key).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Clash {
    /// The object of set A.
    #[serde(with = "super::key_json")]
    pub a: Key,
    /// The object of set B.
    #[serde(with = "super::key_json")]
    pub b: Key,
    /// Its type.
    #[serde(rename = "type")]
    pub kind: ClashKind,
    /// Hard and touch: the penetration, mm (the smallest side of the box
    /// of the meshes' intersection); 0 otherwise.
    pub depth: f64,
    /// Clearance: the least distance between the meshes, mm; 0 otherwise.
    pub distance: f64,
    /// The contact point: the centre of the intersection's box (hard,
    /// touch), midway between the closest points (clearance), the centre
    /// of a's box (duplicate).
    #[serde(with = "point_json")]
    pub point: Point,
    /// Clearance: the closest point of a, then of b.
    #[serde(with = "closest_json", default)]
    pub closest: Option<[Point; 2]>,
    /// Hard and touch: the box of the intersection.
    #[serde(with = "box_json", default)]
    pub overlap: Option<Aabb>,
    /// a's exact box.
    #[serde(with = "box_json_req")]
    pub a_box: Aabb,
    /// b's exact box.
    #[serde(with = "box_json_req")]
    pub b_box: Aabb,
}

impl AsRef<Clash> for Clash {
    fn as_ref(&self) -> &Clash {
        self
    }
}

impl Clash {
    /// A hard clash of depth 1 between integer keys `a` and `b` at point
    /// `p`, for the grouping and status tests.
    #[cfg(test)]
    pub(crate) fn hard_at(a: u64, b: u64, p: Point) -> Clash {
        Clash {
            a: Key::Int(a),
            b: Key::Int(b),
            kind: ClashKind::Hard,
            depth: 1.0,
            distance: 0.0,
            point: p,
            closest: None,
            overlap: None,
            a_box: Aabb::new(p, p),
            b_box: Aabb::new(p, p),
        }
    }

    /// What identifies a clash across runs: its keys and type.
    pub fn id(&self) -> (Key, Key, ClashKind) {
        (self.a.clone(), self.b.clone(), self.kind)
    }
}

/// A point as `[x, y, z]`.
mod point_json {
    use super::Point;
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(p: &Point, s: S) -> Result<S::Ok, S::Error> {
        serde::Serialize::serialize(&[p.x, p.y, p.z], s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Point, D::Error> {
        let a = <[f64; 3]>::deserialize(d)?;
        Ok(Point::new(a[0], a[1], a[2]))
    }
}

/// The closest points as `[[x, y, z], [x, y, z]]`, or null.
mod closest_json {
    use super::Point;
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(p: &Option<[Point; 2]>, s: S) -> Result<S::Ok, S::Error> {
        let v = p.map(|[a, b]| [[a.x, a.y, a.z], [b.x, b.y, b.z]]);
        serde::Serialize::serialize(&v, s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<[Point; 2]>, D::Error> {
        let v = Option::<[[f64; 3]; 2]>::deserialize(d)?;
        Ok(v.map(|[a, b]| [Point::new(a[0], a[1], a[2]), Point::new(b[0], b[1], b[2])]))
    }
}

/// A box as `[x0, y0, z0, x1, y1, z1]`, or null.
mod box_json {
    use super::Aabb;
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(b: &Option<Aabb>, s: S) -> Result<S::Ok, S::Error> {
        serde::Serialize::serialize(&b.map(|b| b.to_array()), s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Aabb>, D::Error> {
        Ok(Option::<[f64; 6]>::deserialize(d)?.map(Aabb::from_array))
    }
}

/// A box as `[x0, y0, z0, x1, y1, z1]`.
mod box_json_req {
    use super::Aabb;
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(b: &Aabb, s: S) -> Result<S::Ok, S::Error> {
        serde::Serialize::serialize(&b.to_array(), s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Aabb, D::Error> {
        Ok(Aabb::from_array(<[f64; 6]>::deserialize(d)?))
    }
}
