//! Cost estimate and progress reports, so that a long build (LAA above
//! all, §3.2: "more expensive in terms of time computing") never runs
//! silently.
//!
//! Work is counted in object visits: dividing a node of n objects, real or
//! trial, is n units (six order scans and six list partitions of n each).
//! [`estimate_work`] predicts that count before a build; the build reports
//! the running count. [`TimeLeft`] turns a bulk load's reports into the
//! time left in each stage, and checks afterwards how well it told it.

use std::sync::atomic::{AtomicU32, AtomicU64, Ordering::Relaxed};
use std::time::{Duration, Instant};

use super::{BuildParams, Method};

/// A snapshot of a running build, passed to the progress callback.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BuildProgress {
    /// Objects already in finished leaves.
    pub objects_placed: u64,
    /// All objects.
    pub objects_total: u64,
    /// Object visits so far, trial subtrees included.
    pub work_done: u64,
    /// The object visits this build is estimated to take.
    pub work_estimate: f64,
    /// LAA: the deepest trial level split so far below a candidate's
    /// children (the look level actually reached; at most the
    /// `look_ahead_level` asked for). 0 for the other methods.
    pub look_level_reached: u32,
}

impl BuildProgress {
    /// This report as a bulk load's [`Stage::Tree`] progress: object
    /// visits, not objects placed, since a `refine` build places none
    /// until its first leaf, after its costliest trials. The total is the
    /// estimate until the work overruns it, or, once objects are placed,
    /// the work done scaled by the share placed when that is less (an
    /// object placed needs no more visits, and the estimate can be a third
    /// off either way: plant 200,000 and 20,000); never less than the work
    /// done.
    pub fn as_stage(&self) -> LoadProgress {
        let done = self.work_done;
        let total = if self.objects_placed >= self.objects_total {
            done
        } else {
            let placed = self.objects_placed as f64 / self.objects_total as f64;
            let by_placed = if placed > 0.0 { done as f64 / placed } else { f64::INFINITY };
            let estimate = if self.work_estimate > done as f64 { self.work_estimate } else { f64::INFINITY };
            let total = estimate.min(by_placed);
            if total.is_finite() { (total as u64).max(done) } else { done }
        };
        LoadProgress { stage: Stage::Tree, done, total }
    }
}

/// Estimated object visits of a build of `objects` objects (see the module
/// doc), for a progress bar or to warn before an expensive LAA.
///
/// It assumes balanced halves: D - 1 internal levels with
/// D = ⌈log2(N / leaf)⌉ + 1, each visiting all N objects; LAA adds, at
/// each level l, six candidates times min(look_ahead_level, D - 2 - l)
/// trial levels, and `refine` the options it trials (about 5 of 7) to
/// the leaves. A low rate R (which allows lopsided cuts) or a
/// lumpy scene gives deeper trees and more work; R = 0 can be quadratic in N. `sizes`
/// serves the byte leaf rule (one object per leaf is assumed without it).
pub fn estimate_work(objects: usize, sizes: Option<&[u64]>, params: &BuildParams) -> f64 {
    let n = objects as f64;
    let per_leaf = params.leaf.objects_per_leaf(sizes);
    if n <= per_leaf {
        return 0.0;
    }
    let internal_levels = (n / per_leaf).log2().ceil().max(1.0) as u32;
    // LAA: six candidates' trials down `look_ahead_level` levels; refine:
    // its options' trials down to the leaves. Of refine's seven options,
    // those that divide a node alike are grown once, and no trial regrows
    // a set of 64 objects or more that an earlier one grew: about four per
    // node on the ship scenes (the test below).
    let (options, look) = match params.method {
        Method::Laa => (6.0, params.look_ahead.levels()),
        Method::Refine => (4.0, u32::MAX),
        _ => (0.0, 0),
    };
    (0..internal_levels).map(|l| n * (1.0 + options * f64::from(look.min(internal_levels - 1 - l)))).sum()
}

/// Reports per thousandth of the objects placed or of the estimated work.
const TICKS: u64 = 1000;

/// The running counts of a build and its throttled reports. The callback
/// may be called from any of rayon's threads, at most about 2 × [`TICKS`]
/// times plus once more per thousandth of the estimate that the work
/// overruns it, and once at the start and at the end.
pub(crate) struct Meter<'a> {
    report: &'a (dyn Fn(BuildProgress) + Sync),
    total: u64,
    estimate: f64,
    work_per_tick: u64,
    placed: AtomicU64,
    work: AtomicU64,
    tick: AtomicU64,
    look: AtomicU32,
}

impl<'a> Meter<'a> {
    pub(crate) fn new(report: &'a (dyn Fn(BuildProgress) + Sync), total: usize, estimate: f64) -> Meter<'a> {
        let meter = Meter {
            report,
            total: total as u64,
            estimate,
            work_per_tick: ((estimate / TICKS as f64) as u64).max(1),
            placed: AtomicU64::new(0),
            work: AtomicU64::new(0),
            tick: AtomicU64::new(0),
            look: AtomicU32::new(0),
        };
        meter.send();
        meter
    }

    /// `n` more objects are in finished leaves.
    pub(crate) fn placed(&self, n: usize) {
        self.placed.fetch_add(n as u64, Relaxed);
        self.maybe_send();
    }

    /// A node of `n` objects was divided (for real or in a trial).
    pub(crate) fn worked(&self, n: usize) {
        self.work.fetch_add(n as u64, Relaxed);
        self.maybe_send();
    }

    /// A trial split nodes `levels` levels below a candidate's children.
    pub(crate) fn reached(&self, levels: u32) {
        self.look.fetch_max(levels, Relaxed);
    }

    /// The final report.
    pub(crate) fn finish(&self) {
        self.send();
    }

    fn maybe_send(&self) {
        let tick = self.placed.load(Relaxed).saturating_mul(TICKS) / self.total.max(1)
            + self.work.load(Relaxed) / self.work_per_tick;
        if self.tick.fetch_max(tick, Relaxed) < tick {
            self.send();
        }
    }

    fn send(&self) {
        (self.report)(BuildProgress {
            objects_placed: self.placed.load(Relaxed),
            objects_total: self.total,
            work_done: self.work.load(Relaxed),
            work_estimate: self.estimate,
            look_level_reached: self.look.load(Relaxed),
        });
    }
}

/// A stage of a bulk load, in the order they run. A later version may add
/// stages.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
#[non_exhaustive]
pub enum Stage {
    /// Clustering objects into the hierarchy (units: object visits, trial
    /// subtrees included, as [`BuildProgress::work_done`] counts them, of a
    /// total from [`BuildProgress::work_estimate`]: see
    /// [`BuildProgress::as_stage`]).
    Tree,
    /// Placing records in geometry and node blocks (one unit).
    Layout,
    /// Voxelizing leaf entries' candidate bounds and judging which pay,
    /// block by block (units: geometry blocks).
    Levels,
    /// Keeping the bounds that pay as a whole, and measuring their error (units: steps).
    Choose,
    /// Writing geometry blocks (units: blocks).
    Geometry,
    /// Building the group bounds b(S_n,k) of every node: level 2 under the
    /// finer group grid, to learn whether its bounds fit, then every level
    /// under the grid chosen (units: a node's levels built, in both passes).
    Groups,
    /// Writing node blocks (units: node blocks).
    Nodes,
    /// Writing the key index (units: objects, as their entries are made).
    Keys,
}

impl Stage {
    /// The stage's name, as the CLI prints it.
    pub fn name(self) -> &'static str {
        match self {
            Stage::Tree => "tree",
            Stage::Layout => "layout",
            Stage::Levels => "levels",
            Stage::Choose => "choose",
            Stage::Geometry => "geometry",
            Stage::Groups => "groups",
            Stage::Nodes => "nodes",
            Stage::Keys => "keys",
        }
    }
}

/// Where a bulk load is: `done` of `total` units of `stage`. Each stage
/// reports once with `done` = 0, throttled as it goes, and once with
/// `done` = `total`, so a caller can show a bar and the time left per stage.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LoadProgress {
    /// The stage.
    pub stage: Stage,
    /// Units done so far.
    pub done: u64,
    /// Units in the stage.
    pub total: u64,
}

/// A stage's running count and its throttled reports (per thousandth).
pub(crate) struct StageMeter<'a> {
    report: &'a (dyn Fn(LoadProgress) + Sync),
    stage: Stage,
    total: u64,
    done: AtomicU64,
    tick: AtomicU64,
}

impl<'a> StageMeter<'a> {
    pub(crate) fn new(report: &'a (dyn Fn(LoadProgress) + Sync), stage: Stage, total: u64) -> StageMeter<'a> {
        report(LoadProgress { stage, done: 0, total });
        StageMeter { report, stage, total, done: AtomicU64::new(0), tick: AtomicU64::new(0) }
    }

    /// Counts up to `done` units, when fewer are done: work a stage found
    /// it did not need.
    pub(crate) fn catch_up(&self, done: u64) {
        let now = self.done.load(Relaxed);
        if now < done {
            self.add(done - now);
        }
    }

    /// `n` more units are done.
    pub(crate) fn add(&self, n: u64) {
        let done = self.done.fetch_add(n, Relaxed) + n;
        let tick = done.saturating_mul(TICKS) / self.total.max(1);
        if self.tick.fetch_max(tick, Relaxed) < tick {
            (self.report)(LoadProgress { stage: self.stage, done: done.min(self.total), total: self.total });
        }
    }
}

impl Drop for StageMeter<'_> {
    /// The stage's last report says it is done, however it counted.
    fn drop(&mut self) {
        (self.report)(LoadProgress { stage: self.stage, done: self.total, total: self.total });
    }
}

/// Shares of a stage's wall time at which [`TimeLeft::end`] checks what
/// was told.
pub const TIME_LEFT_CHECKS: [f64; 5] = [0.1, 0.25, 0.5, 0.75, 0.9];

/// The time left in each stage of a bulk load, from its [`LoadProgress`]
/// reports: the units left at the mean rate since the stage's units began
/// to move (the first report with some done). Not a recent rate, which
/// swings where units cost unevenly (a trial's large nodes, then its small
/// ones); and not from the stage's start, which would spread over every
/// unit the setup no unit counts (the tree stage's six sorted orders, 5%
/// of it at 10^7 objects). It keeps what it told, so that
/// [`TimeLeft::end`] can say how close it came.
#[derive(Debug, Default)]
pub struct TimeLeft {
    /// The stage reported last, and when its first report came.
    current: Option<(Stage, Instant)>,
    /// When the current stage's first report with units done came, and
    /// how many were done then.
    moving: Option<(Instant, u64)>,
    /// Per report of the current stage that told a time: (seconds into
    /// the stage, seconds told left).
    told: Vec<(f64, f64)>,
}

/// How the time left told at one point of a stage compared with the time
/// the stage then took.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct TimeLeftCheck {
    /// The share of the stage's wall time this check is at (one of
    /// [`TIME_LEFT_CHECKS`]).
    pub at: f64,
    /// The time left told by the last report at or before that point, in
    /// seconds; none when no report had told one yet.
    pub told_seconds: Option<f64>,
    /// The time the stage took from that report on, in seconds.
    pub actual_seconds: f64,
    /// Told over actual, less one: 0.25 is a quarter too long, -0.25 a
    /// quarter too short. None when nothing was told, or nothing was left.
    pub error: Option<f64>,
}

impl TimeLeftCheck {
    fn new(at: f64, told_seconds: Option<f64>, actual_seconds: f64) -> TimeLeftCheck {
        let error = told_seconds.filter(|_| actual_seconds > 0.0).map(|t| t / actual_seconds - 1.0);
        TimeLeftCheck { at, told_seconds, actual_seconds, error }
    }
}

impl TimeLeft {
    /// A clock with no stage begun.
    pub fn new() -> TimeLeft {
        TimeLeft::default()
    }

    /// Takes report `p`, made at `now`, and returns the time left in its
    /// stage, once a hundredth of its units are done and some since they
    /// began to move. A report of another
    /// stage than the last begins that stage: call [`TimeLeft::end`] first
    /// to check the one before.
    pub fn observe(&mut self, p: &LoadProgress, now: Instant) -> Option<Duration> {
        let began = match self.current {
            Some((stage, began)) if stage == p.stage => began,
            _ => {
                self.current = Some((p.stage, now));
                self.moving = None;
                self.told.clear();
                now
            }
        };
        if p.done == 0 {
            return None;
        }
        let (moved, done_then) = *self.moving.get_or_insert((now, p.done));
        if p.done <= done_then || p.done.saturating_mul(100) < p.total {
            return None;
        }
        let moving_for = now.saturating_duration_since(moved).as_secs_f64();
        let left = moving_for * p.total.saturating_sub(p.done) as f64 / (p.done - done_then) as f64;
        self.told.push((now.saturating_duration_since(began).as_secs_f64(), left));
        Some(Duration::from_secs_f64(left))
    }

    /// Ends the current stage at `now` and checks, at each share of its
    /// wall time in [`TIME_LEFT_CHECKS`], the time left told then against
    /// the time it took. Empty when no stage was begun.
    pub fn end(&mut self, now: Instant) -> Vec<TimeLeftCheck> {
        let Some((_, began)) = self.current.take() else { return Vec::new() };
        let told = std::mem::take(&mut self.told);
        let seconds = now.saturating_duration_since(began).as_secs_f64();
        TIME_LEFT_CHECKS
            .iter()
            .map(|&at| {
                // Reports come in time order: the last one at or before the point.
                let last = told.partition_point(|&(t, _)| t <= at * seconds).checked_sub(1).map(|i| told[i]);
                match last {
                    Some((t, left)) => TimeLeftCheck::new(at, Some(left), seconds - t),
                    None => TimeLeftCheck::new(at, None, seconds * (1.0 - at)),
                }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bulk::{LeafRule, LookAhead};

    #[test]
    fn the_tree_stage_counts_visits_of_the_estimate_or_of_the_share_placed_and_ends_done() {
        let at = |placed, done, estimate| {
            let p = BuildProgress {
                objects_placed: placed,
                objects_total: 100,
                work_done: done,
                work_estimate: estimate,
                look_level_reached: 0,
            };
            let s = p.as_stage();
            assert_eq!((s.stage, s.done), (Stage::Tree, done));
            s.total
        };
        // Nothing placed: the estimate, or the work done past it.
        assert_eq!(at(0, 300, 1000.0), 1000);
        assert_eq!(at(0, 1200, 1000.0), 1200);
        // Past the estimate with a quarter placed: by the share placed.
        assert_eq!(at(25, 1200, 1000.0), 4800);
        // A quarter placed after 400 visits: 1600 is more than the estimate.
        assert_eq!(at(25, 400, 1000.0), 1000);
        // Half placed after 400 visits: 800, less than the estimate.
        assert_eq!(at(50, 400, 1000.0), 800);
        // Every object placed: the build is done, whatever the estimate.
        assert_eq!(at(100, 700, 1000.0), 700);
        assert_eq!(at(100, 1300, 1000.0), 1300);
    }

    #[test]
    fn time_left_is_the_mean_rate_since_units_began_to_move_and_is_checked_at_its_end() {
        let t0 = Instant::now();
        let at = |s: f64| t0 + Duration::from_secs_f64(s);
        let report = |stage, done| LoadProgress { stage, done, total: 100 };
        let mut clock = TimeLeft::new();
        assert_eq!(clock.end(t0), []);
        assert_eq!(clock.observe(&report(Stage::Levels, 0), at(0.0)), None);
        // A setup that counts no unit, then units begin to move: the first
        // report with some done tells nothing.
        assert_eq!(clock.observe(&report(Stage::Levels, 0), at(0.5)), None);
        assert_eq!(clock.observe(&report(Stage::Levels, 10), at(1.0)), None);
        // 20 units in the 2 s since: 0.1 s a unit, so 7 s for the 70 left,
        // whatever the setup took; then 50 in 5 s, 4 s for the 40 left.
        assert_eq!(clock.observe(&report(Stage::Levels, 30), at(3.0)), Some(Duration::from_secs(7)));
        assert_eq!(clock.observe(&report(Stage::Levels, 60), at(6.0)), Some(Duration::from_secs(4)));
        let checks = clock.end(at(10.0));
        let shares: Vec<f64> = checks.iter().map(|c| c.at).collect();
        assert_eq!(shares, TIME_LEFT_CHECKS);
        // At 1 s and 2.5 s nothing had been told; at 5 s the 3 s report's
        // 7 s against 7 s taken; at 9 s the 6 s report's 4 s against 4 s.
        let check = |at, told_seconds, actual_seconds, error| TimeLeftCheck {
            at,
            told_seconds,
            actual_seconds,
            error,
        };
        assert_eq!(checks[0], check(0.1, None, 9.0, None));
        assert_eq!(checks[1], check(0.25, None, 7.5, None));
        assert_eq!(checks[2], check(0.5, Some(7.0), 7.0, Some(0.0)));
        assert_eq!(checks[4], check(0.9, Some(4.0), 4.0, Some(0.0)));
        // A new stage starts its own clock.
        assert_eq!(clock.observe(&report(Stage::Groups, 10), at(20.0)), None);
        assert_eq!(clock.observe(&report(Stage::Groups, 20), at(21.0)), Some(Duration::from_secs(8)));
    }

    #[test]
    fn a_stage_reports_its_start_at_most_a_thousand_steps_and_its_end() {
        let seen = std::sync::Mutex::new(Vec::new());
        let report = |p: LoadProgress| seen.lock().unwrap().push(p);
        {
            let meter = StageMeter::new(&report, Stage::Levels, 10_000);
            for _ in 0..10_000 {
                meter.add(1);
            }
        }
        let seen = seen.into_inner().unwrap();
        assert_eq!(seen[0], LoadProgress { stage: Stage::Levels, done: 0, total: 10_000 });
        assert_eq!(seen[seen.len() - 1].done, 10_000);
        assert!(seen.len() <= 1002, "{} reports", seen.len());
        assert!(seen.windows(2).all(|w| w[0].done <= w[1].done));
    }

    #[test]
    fn the_estimate_grows_with_look_ahead_and_vanishes_for_one_page() {
        let moa = BuildParams { leaf: LeafRule::Objects(100), ..BuildParams::paper() };
        let laa = |look_ahead| BuildParams { method: Method::Laa, look_ahead, ..moa.clone() };
        assert_eq!(estimate_work(100, None, &moa), 0.0);
        let w = |p: &BuildParams| estimate_work(100_000, None, p);
        // 1000 pages: 10 internal levels of 100 000 visits.
        assert_eq!(w(&moa), 1.0e6);
        assert_eq!(w(&laa(LookAhead::Levels(0))), w(&moa));
        assert!(w(&laa(LookAhead::Levels(2))) > w(&moa));
        assert!(w(&laa(LookAhead::Max)) > w(&laa(LookAhead::Levels(2))));
        assert_eq!(w(&laa(LookAhead::Max)), w(&laa(LookAhead::Levels(9))));
    }

    /// The estimate is what a progress message promises: 0.7 to 1.2 times
    /// the work each method does on a ship scene (refine's was 1.25 times
    /// when it counted all seven options, and again when its trials began
    /// to share the sets they grow).
    #[test]
    fn the_estimate_is_near_the_work_done() {
        use crate::bulk::build;
        use crate::scene::generate::{GenOptions, Preset, generate_scene};
        let scene =
            generate_scene(&GenOptions { preset: Preset::Ship, objects: Some(20_000), seed: 0 }).unwrap();
        let boxes = scene.object_boxes();
        for method in [Method::Moa, Method::Laa, Method::Refine] {
            for leaf in [LeafRule::Objects(1), LeafRule::Objects(20)] {
                let params = BuildParams { method, leaf, ..BuildParams::paper() };
                let done = AtomicU64::new(0);
                build(&boxes, None, &params, &|p: BuildProgress| done.store(p.work_done, Relaxed)).unwrap();
                let ratio = estimate_work(boxes.len(), None, &params) / done.into_inner() as f64;
                assert!((0.7..1.2).contains(&ratio), "{method:?} {leaf:?}: estimate / work = {ratio:.2}");
            }
        }
    }
}
