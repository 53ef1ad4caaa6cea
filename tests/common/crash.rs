//! The crash loop shared by the crash tests: a commit crashed at each of
//! its device events, the image kept in every way a crash can leave it.

use std::fmt::Debug;
use std::sync::Arc;

use mktree::db::{Database, Warning, check};
use mktree::store::BlockDevice;
use mktree::store::device::{CrashDevice, CrashImage, MemDevice};

/// What a crash can leave of the unsynced writes.
pub const MODES: [CrashImage; 5] = [
    CrashImage::DropAll,
    CrashImage::KeepAll,
    CrashImage::TearLast,
    CrashImage::Mask(0x5555_5555_5555_5555),
    CrashImage::Mask(0xF0F0_0F0F_3333_CCCC),
];

/// Runs `commit` on `image` crashed at each of its `events` device events;
/// each reopened image must give `old` or `new` by `fingerprint` and pass
/// `check`, and where it gives `old`, `commit` run again must give `new`.
/// Returns how often each side came back (old, new), and how often the
/// old came back because a commit synced once had not reached the disk whole.
pub fn every_crash_reopens_at_one_side<T: PartialEq + Debug>(
    image: &[u8],
    events: u64,
    commit: impl Fn(&Database) -> bool,
    fingerprint: impl Fn(&Database) -> T,
    old: &T,
    new: &T,
) -> [usize; 3] {
    let mut outcomes = [0usize; 3];
    for crash_at in 0..events {
        let dev = Arc::new(CrashDevice::new(image.to_vec(), crash_at));
        let db = Database::open_on(dev.clone() as Arc<dyn BlockDevice>).unwrap();
        assert!(!commit(&db), "crash at event {crash_at} must fail the commit");
        drop(db);
        for mode in MODES {
            let after = Arc::new(MemDevice::from_bytes(dev.image(mode)));
            let db = Database::open_on(after as Arc<dyn BlockDevice>)
                .unwrap_or_else(|e| panic!("crash at {crash_at} ({mode:?}): reopen failed: {e}"));
            let got = fingerprint(&db);
            assert!(got == *old || got == *new, "crash at {crash_at} ({mode:?}) gave a mix");
            outcomes[usize::from(got == *new)] += 1;
            if db.warnings().iter().any(|w| matches!(w, Warning::UnfinishedCommit { .. })) {
                assert!(got == *old, "crash at {crash_at} ({mode:?}): an unfinished commit was read");
                outcomes[2] += 1;
            }
            let report = check(&db).unwrap();
            assert!(report.ok(), "crash at {crash_at} ({mode:?}): check: {:?}", report.faults);
            if got == *old {
                // The next writer cleans up after the crash, and the commit goes through.
                assert!(commit(&db), "crash at {crash_at} ({mode:?}): the commit again failed");
                assert!(fingerprint(&db) == *new, "crash at {crash_at} ({mode:?}): the commit again differs");
                let report = check(&db).unwrap();
                assert!(report.ok(), "crash at {crash_at} ({mode:?}): check after: {:?}", report.faults);
            }
        }
    }
    outcomes
}
