//! OBJ import's vertices (see `obj.rs`): the file's vertices as its pieces
//! parsed them, with the oldest spilled to disk in a streamed import.

use std::path::PathBuf;

use crate::geom::Point;
use crate::spill::SpillFile;

/// The file's vertices, kept in the vectors its pieces parsed them into:
/// copying them into one would be a step no other core could share. A
/// face may name any earlier vertex, so all are kept; with a spill file
/// (streamed imports), runs beyond the newest [`RESIDENT_VERTEX_BYTES`]
/// go to disk and are read back only when a face names them.
#[derive(Default)]
pub(super) struct Vertices {
    runs: Vec<Run>,
    /// The file index of each run's first vertex.
    starts: Vec<u64>,
    len: u64,
    spill: Option<SpillFile>,
    /// Bytes of runs kept in memory with a spill file.
    keep: usize,
    /// Bytes of the runs in memory, and the oldest of them.
    resident: usize,
    oldest_resident: usize,
}

/// Vertex bytes a streamed import keeps in memory: far more than any
/// object's own vertices, which faces name in practice.
pub(super) const RESIDENT_VERTEX_BYTES: usize = 64 << 20;

/// Bytes of a vertex in the spill file: three f64.
const SPILLED_VERTEX: usize = 24;

enum Run {
    Resident(Vec<Point>),
    Spilled { offset: u64, len: usize },
}

impl Run {
    fn len(&self) -> usize {
        match self {
            Run::Resident(points) => points.len(),
            Run::Spilled { len, .. } => *len,
        }
    }
}

impl Vertices {
    pub(super) fn spilling(spill: SpillFile, keep: usize) -> Vertices {
        Vertices { spill: Some(spill), keep, ..Vertices::default() }
    }

    pub(super) fn len(&self) -> u64 {
        self.len
    }

    pub(super) fn append(&mut self, run: Vec<Point>) -> std::io::Result<()> {
        if run.is_empty() {
            return Ok(());
        }
        self.starts.push(self.len);
        self.len += run.len() as u64;
        self.resident += run.len() * SPILLED_VERTEX;
        self.runs.push(Run::Resident(run));
        let Some(spill) = &mut self.spill else { return Ok(()) };
        // The newest run always stays: the next faces most likely name it.
        while self.resident > self.keep && self.oldest_resident + 1 < self.runs.len() {
            let run = &mut self.runs[self.oldest_resident];
            if let Run::Resident(points) = run {
                let bytes: Vec<u8> =
                    points.iter().flat_map(|p| p.coords.iter()).flat_map(|c| c.to_le_bytes()).collect();
                let offset = spill.append(&bytes)?;
                self.resident -= points.len() * SPILLED_VERTEX;
                *run = Run::Spilled { offset, len: points.len() };
            }
            self.oldest_resident += 1;
        }
        spill.flush()
    }

    /// The run holding vertex `index`, and where in it; past the end, the
    /// end of the last run.
    fn locate(&self, index: u32) -> (usize, usize) {
        let run = self.starts.partition_point(|&start| start <= u64::from(index)).saturating_sub(1);
        let at = u64::from(index).saturating_sub(self.starts.get(run).copied().unwrap_or(0));
        (run, (at as usize).min(self.runs.get(run).map_or(0, Run::len)))
    }

    /// Vertex `index`, which the faces' checks put below `len`.
    pub(super) fn get(&self, index: u32) -> std::io::Result<Point> {
        let mut point = Point::origin();
        self.for_range(index, 1, &mut |run| point = run.first().copied().unwrap_or(point))?;
        Ok(point)
    }

    /// Hands `f` the vertices from `index` on, run by run, up to `count`
    /// of them (fewer at the end), reading spilled runs back.
    pub(super) fn for_range(
        &self,
        index: u32,
        count: usize,
        f: &mut dyn FnMut(&[Point]),
    ) -> std::io::Result<()> {
        let (first, mut at) = self.locate(index);
        let mut left = count;
        let mut buffer = Vec::new();
        for run in self.runs.get(first..).unwrap_or_default() {
            if left == 0 {
                break;
            }
            let take = left.min(run.len().saturating_sub(at));
            match run {
                Run::Resident(points) => f(&points[at..at + take]),
                Run::Spilled { offset, .. } => {
                    let spill = self.spill.as_ref().ok_or_else(|| std::io::Error::other("no spill file"))?;
                    let mut bytes = vec![0u8; take * SPILLED_VERTEX];
                    spill.read_exact_at(&mut bytes, offset + (at * SPILLED_VERTEX) as u64)?;
                    buffer.clear();
                    buffer.extend(bytes.chunks_exact(SPILLED_VERTEX).map(|v| {
                        let c =
                            |i: usize| f64::from_le_bytes(v[8 * i..8 * i + 8].try_into().unwrap_or([0; 8]));
                        Point::new(c(0), c(1), c(2))
                    }));
                    f(&buffer);
                }
            }
            left -= take;
            at = 0;
        }
        Ok(())
    }

    pub(super) fn spill_path(&self) -> PathBuf {
        self.spill.as_ref().map_or_else(PathBuf::new, |s| s.path().to_path_buf())
    }
}
