//! A device that models a volatile write cache and a crash: writes reach the
//! durable image only at a sync; a crash at a chosen write or sync stops the
//! device, and the image after the crash keeps, drops or tears each write that
//! was not yet synced.

use std::io;
use std::sync::Mutex;

use super::BlockDevice;
use super::mem::write_into;

/// What happens to an unsynced write in the image after a crash.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CrashImage {
    /// Every unsynced write is lost.
    DropAll,
    /// Every unsynced write landed.
    KeepAll,
    /// Every unsynced write landed except the last, of which only the first half did.
    TearLast,
    /// Unsynced writes land or not by the bits of this mask (write i lands when bit i % 64 is set).
    Mask(u64),
}

#[derive(Debug, Default)]
struct State {
    durable: Vec<u8>,
    current: Vec<u8>,
    unsynced: Vec<(u64, Vec<u8>)>,
    events: u64,
    crashed: bool,
}

/// An in-memory device that crashes at its `crash_at`-th write or sync (0-based).
#[derive(Debug)]
pub struct CrashDevice {
    state: Mutex<State>,
    crash_at: u64,
}

impl CrashDevice {
    /// A device starting from `image` (durable), crashing at event `crash_at`
    /// (`u64::MAX`: never).
    pub fn new(image: Vec<u8>, crash_at: u64) -> CrashDevice {
        let state = State { durable: image.clone(), current: image, ..State::default() };
        CrashDevice { state: Mutex::new(state), crash_at }
    }

    /// Writes and syncs seen so far (the event that crashed included).
    pub fn events(&self) -> u64 {
        self.lock().events
    }

    /// True once the crash happened.
    pub fn crashed(&self) -> bool {
        self.lock().crashed
    }

    /// The bytes a disk would hold after the crash (or now, if none happened).
    pub fn image(&self, mode: CrashImage) -> Vec<u8> {
        let s = self.lock();
        let mut img = s.durable.clone();
        let n = s.unsynced.len();
        for (i, (off, data)) in s.unsynced.iter().enumerate() {
            let keep: &[u8] = match mode {
                CrashImage::DropAll => continue,
                CrashImage::KeepAll => data,
                CrashImage::TearLast if i + 1 == n => &data[..data.len() / 2],
                CrashImage::TearLast => data,
                CrashImage::Mask(m) if m >> (i % 64) & 1 == 1 => data,
                CrashImage::Mask(_) => continue,
            };
            // Each write's range was checked when it was made: this cannot fail.
            let _ = write_into(&mut img, *off, keep);
        }
        img
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Counts one write or sync; fails it (and all later operations) at the crash point.
    fn event(&self, s: &mut State) -> io::Result<()> {
        if s.crashed {
            return Err(io::Error::other("device crashed"));
        }
        let e = s.events;
        s.events += 1;
        if e == self.crash_at {
            s.crashed = true;
            return Err(io::Error::other("device crashed"));
        }
        Ok(())
    }
}

impl BlockDevice for CrashDevice {
    fn read_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<()> {
        let s = self.lock();
        if s.crashed {
            return Err(io::Error::other("device crashed"));
        }
        let start = offset as usize;
        let src = s
            .current
            .get(start..start + buf.len())
            .ok_or_else(|| io::Error::from(io::ErrorKind::UnexpectedEof))?;
        buf.copy_from_slice(src);
        Ok(())
    }
    fn write_at(&self, offset: u64, data: &[u8]) -> io::Result<()> {
        let mut s = self.lock();
        self.event(&mut s)?;
        write_into(&mut s.current, offset, data)?;
        s.unsynced.push((offset, data.to_vec()));
        Ok(())
    }
    fn sync(&self) -> io::Result<()> {
        let mut s = self.lock();
        self.event(&mut s)?;
        // The durable image plus the unsynced writes is the current one:
        // applying them costs the bytes written, not the file's size.
        let State { durable, unsynced, .. } = &mut *s;
        for (off, data) in unsynced.drain(..) {
            write_into(durable, off, &data)?;
        }
        Ok(())
    }
    fn len(&self) -> io::Result<u64> {
        Ok(self.lock().current.len() as u64)
    }
    fn set_len(&self, len: u64) -> io::Result<()> {
        let mut s = self.lock();
        if s.crashed {
            return Err(io::Error::other("device crashed"));
        }
        // Length changes are applied to both images: the commit protocol only
        // truncates during recovery, after a sync.
        s.current.resize(len as usize, 0);
        s.durable.resize(len as usize, 0);
        // A write cut off by the new length lands no further than it.
        for (off, data) in &mut s.unsynced {
            data.truncate(len.saturating_sub(*off) as usize);
        }
        Ok(())
    }
    fn writes_are_atomic(&self) -> bool {
        true
    }
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;

    #[derive(Debug, Clone)]
    enum Op {
        Write(u64, Vec<u8>),
        Sync,
        SetLen(u64),
    }

    fn op() -> impl Strategy<Value = Op> {
        prop_oneof![
            4 => (0u64..3000, proptest::collection::vec(any::<u8>(), 0..300)).prop_map(|(o, d)| Op::Write(o, d)),
            1 => Just(Op::Sync),
            1 => (0u64..3500).prop_map(Op::SetLen),
        ]
    }

    fn read_all(d: &CrashDevice) -> Vec<u8> {
        let mut buf = vec![0; d.len().unwrap() as usize];
        d.read_at(0, &mut buf).unwrap();
        buf
    }

    proptest! {
        /// The image with every unsynced write kept is what reads see, and
        /// after a sync no write is pending: dropping them changes nothing.
        #[test]
        fn syncs_make_the_current_image_durable(start in proptest::collection::vec(any::<u8>(), 0..500),
                                                ops in proptest::collection::vec(op(), 0..40)) {
            let d = CrashDevice::new(start, u64::MAX);
            for op in ops {
                match op {
                    Op::Write(o, data) => d.write_at(o, &data).unwrap(),
                    Op::Sync => {
                        d.sync().unwrap();
                        prop_assert_eq!(d.image(CrashImage::DropAll), read_all(&d));
                    }
                    Op::SetLen(n) => d.set_len(n).unwrap(),
                }
                prop_assert_eq!(d.image(CrashImage::KeepAll), read_all(&d));
            }
        }
    }

    #[test]
    fn a_write_past_the_address_space_is_an_error_and_lands_nowhere() {
        let d = CrashDevice::new(vec![1; 8], u64::MAX);
        assert!(d.write_at(u64::MAX - 1, &[2, 2, 2]).is_err());
        d.sync().unwrap();
        assert_eq!(d.image(CrashImage::KeepAll), [1; 8]);
        assert_eq!(read_all(&d), [1; 8]);
    }

    #[test]
    fn a_crash_drops_what_was_not_synced() {
        let d = CrashDevice::new(vec![1; 8], 2);
        d.write_at(0, &[2, 2]).unwrap();
        d.sync().unwrap();
        d.write_at(4, &[3, 3]).unwrap_err();
        assert!(d.crashed());
        assert_eq!(d.image(CrashImage::DropAll), [2, 2, 1, 1, 1, 1, 1, 1]);
        assert!(d.read_at(0, &mut [0; 2]).is_err());
    }
}
