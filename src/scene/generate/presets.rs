//! The presets: the paper's three oil-tanker scenes (Table 1, §2) and the
//! open-ended `ship`, each as a grid of compartments with an object budget.
//!
//! A preset fixes a compartment size and how many compartments hold its
//! object count. The grid's outer box is Table 1's extent, and the structure
//! of the outermost compartments closes it, so the extent is exact. Asking
//! for more objects adds compartments along x (a longer hull), keeping the
//! objects per compartment, so the extent grows with the count.
//!
//! | preset  | objects | triangles | extent (mm)            | grid (x, y, z) |
//! |---------|---------|-----------|------------------------|----------------|
//! | tanker1 | 222     | 3,989     | 3920 x 1935 x 1308     | 1 x 1 x 1 skid |
//! | tanker2 | 3,900   | 106,703   | 17294 x 12924 x 27351  | 2 x 2 x 5      |
//! | tanker3 | 4,096   | 132,557   | 22087 x 7965 x 10301   | 3 x 1 x 2      |
//! | ship    | 10,000  | 30 / obj. | 10 m per 3,000 objects | n x 2 x 3      |
//! | plant   | 20,000  | about 60 / obj. | 6 m of rack per 120 objects | bays, 50 a row |
//!
//! Tanker 1 is "an equipment element" (Figure 5): one skid, a pump unit and
//! its piping in a steel frame. Tankers 2 and 3 are engine- and pump-room
//! blocks (Figures 6 and 7).

use std::ops::RangeInclusive;

use super::GenError;

/// A scene preset: one of Table 1's tankers, or an open-ended ship.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Preset {
    /// Oil tanker 1 of Table 1: an equipment skid, 222 objects.
    Tanker1,
    /// Oil tanker 2 of Table 1: 3,900 objects in a 17 x 13 x 27 m block.
    Tanker2,
    /// Oil tanker 3 of Table 1: 4,096 objects in a 22 x 8 x 10 m block.
    Tanker3,
    /// A hull of compartments along x, 100 to 10^7 objects (10,000 unless asked).
    Ship,
    /// A process plant's pipe racks and equipment, 100 to 10^7 objects
    /// (20,000 unless asked): not one of the paper's scenes, and not one the
    /// project tunes on (`plant.rs`).
    Plant,
}

impl Preset {
    /// Every preset, in table order.
    pub const ALL: [Preset; 5] =
        [Preset::Tanker1, Preset::Tanker2, Preset::Tanker3, Preset::Ship, Preset::Plant];

    /// The name used on the command line and in file headers.
    pub fn name(self) -> &'static str {
        match self {
            Preset::Tanker1 => "tanker1",
            Preset::Tanker2 => "tanker2",
            Preset::Tanker3 => "tanker3",
            Preset::Ship => "ship",
            Preset::Plant => "plant",
        }
    }

    /// The object count when none is asked for (Table 1's for the tankers).
    pub fn default_objects(self) -> u64 {
        match self.layout() {
            Some(l) if self != Preset::Ship => l.objects,
            Some(_) => 10_000,
            None => 20_000,
        }
    }

    /// The object counts this preset accepts.
    pub fn object_range(self) -> RangeInclusive<u64> {
        100..=10_000_000
    }

    /// The compartment grid and targets behind a hull or skid preset; none
    /// for the plant, which is laid out by bays (`plant.rs`).
    pub(crate) fn layout(self) -> Option<Layout> {
        let (structure, extent, grid, objects, triangles) = match self {
            Preset::Plant => return None,
            Preset::Tanker1 => (Structure::Skid, [3920.0, 1935.0, 1308.0], [1, 1, 1], 222, 3_989),
            Preset::Tanker2 => (Structure::Hull, [17294.0, 12924.0, 27351.0], [2, 2, 5], 3_900, 106_703),
            Preset::Tanker3 => (Structure::Hull, [22087.0, 7965.0, 10301.0], [3, 1, 2], 4_096, 132_557),
            // One slice of the ship: 2 compartments across, 3 decks, 500 objects each.
            Preset::Ship => (Structure::Hull, [10000.0, 16000.0, 15000.0], [1, 2, 3], 3_000, 90_000),
        };
        let cell_mm = std::array::from_fn(|i| extent[i] / grid[i] as f64);
        Some(Layout {
            structure,
            cell_mm,
            across: grid[1],
            decks: grid[2],
            objects,
            compartments: grid.iter().product(),
            triangles_per_object: triangles as f64 / objects as f64,
        })
    }
}

impl std::fmt::Display for Preset {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Preset {
    type Err = GenError;

    fn from_str(s: &str) -> Result<Preset, GenError> {
        Preset::ALL
            .into_iter()
            .find(|p| p.name() == s)
            .ok_or_else(|| GenError::UnknownPreset { name: s.to_string() })
    }
}

/// What bounds each compartment.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Structure {
    /// An equipment skid: a base frame and deck plate, corner posts and top
    /// rails, all rectangular sections; supports stand on the deck plate.
    Skid,
    /// Hull structure: decks, bulkheads and shell plating with stiffeners,
    /// web frames overhead; supports hang from the deck above.
    Hull,
}

/// A preset's compartment grid and targets.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Layout {
    pub(crate) structure: Structure,
    /// One compartment's size.
    pub(crate) cell_mm: [f64; 3],
    /// Compartments per slice across the hull (y) and in height (z).
    pub(crate) across: u64,
    pub(crate) decks: u64,
    /// The preset's reference object count and the compartments that hold it.
    pub(crate) objects: u64,
    pub(crate) compartments: u64,
    /// The average the emitter steers towards.
    pub(crate) triangles_per_object: f64,
}

impl Layout {
    /// Compartments for `objects`: as many as keep the preset's objects per
    /// compartment, rounded up, so the reference count gives the reference grid.
    pub(crate) fn compartments_for(&self, objects: u64) -> u64 {
        (objects * self.compartments).div_ceil(self.objects)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_parse_back_to_their_preset() {
        for p in Preset::ALL {
            assert_eq!(p.name().parse::<Preset>().unwrap(), p);
        }
        assert!(matches!("tanker4".parse::<Preset>(), Err(GenError::UnknownPreset { .. })));
    }

    #[test]
    fn reference_counts_fill_the_reference_grid() {
        for p in Preset::ALL {
            let Some(l) = p.layout() else { continue };
            assert_eq!(l.compartments_for(l.objects), l.compartments, "{p}");
            assert_eq!(l.compartments % (l.across * l.decks), 0, "{p}: whole slices");
        }
        let ship = Preset::Ship.layout().unwrap();
        assert_eq!(ship.compartments_for(100), 1);
        assert_eq!(ship.compartments_for(10_000_000), 20_000);
    }
}
