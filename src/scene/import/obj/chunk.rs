//! OBJ import's chunking (see `obj.rs`): the input read in blocks, three
//! at a time in a pipeline, each block cut after newlines into pieces that
//! rayon parses at once.

use std::io::Read;
use std::ops::Range;
use std::path::Path;

use rayon::prelude::*;

use super::Grouping;
use super::statement::{Piece, find_newline};
use super::stitch::{Built, Stitcher};
use super::vertices::Vertices;
use crate::scene::Object;
use crate::scene::import::ImportError;

/// How the input is cut: blocks read at a time, and pieces parsed at once.
#[derive(Debug, Clone, Copy)]
pub(super) struct Chunking {
    /// Bytes read per block (more when a line is longer).
    pub(super) block: usize,
    /// Bytes per piece, up to the next newline.
    pub(super) piece: usize,
}

impl Chunking {
    /// Blocks big enough that a read costs little per byte and a block has
    /// pieces for every core, small enough to stay mapped between reads and
    /// to start the cores soon; pieces small enough that the last one of a
    /// block leaves the other cores idle only briefly.
    pub(super) const DEFAULT: Chunking = Chunking { block: 8 << 20, piece: 512 << 10 };
}

/// The reading loop: blocks in, objects out through `on_object`.
pub(super) fn parse<R: Read + Send>(
    mut reader: R,
    source: &Path,
    grouping: Grouping,
    chunking: Chunking,
    vertices: Vertices,
    mut on_object: impl FnMut(Object),
) -> Result<usize, ImportError> {
    let mut stitcher = Stitcher::new(source, grouping, vertices);
    let mut degenerate_triangles = 0;
    let mut emit = |built: Built| -> Result<(), ImportError> {
        for result in built.objects {
            let (object, degenerate) = result?;
            degenerate_triangles += degenerate;
            on_object(object);
        }
        built.error.map_or(Ok(()), Err)
    };
    // Three blocks at once: one is read, the one before is cut into pieces
    // that are parsed, and the one before that is stitched and built.
    let mut block = Vec::new();
    let mut input = read_block(&mut reader, &mut block, chunking.block);
    let mut parsed: Option<Parsed> = None;
    let mut spare = Vec::new();
    loop {
        let complete = block.iter().rposition(|&b| b == b'\n').map_or(0, |i| i + 1);
        let end = match input {
            Input::More if complete == 0 => {
                // A line longer than the block: read on into the same block.
                input = read_block(&mut reader, &mut block, chunking.block);
                continue;
            }
            // After a failed read, the lines before it count first, as
            // they would for a reader that reads line by line.
            Input::More | Input::Failed(_) => complete,
            Input::Ended => block.len(),
        };
        let more = matches!(input, Input::More);
        if more {
            // The next block starts with this one's unfinished line.
            spare.clear();
            spare.extend_from_slice(&block[complete..]);
        }
        let text = &block[..end];
        let (built, (pieces, next)) = rayon::join(
            || parsed.as_mut().map(|parsed| stitcher.block(parsed)),
            || {
                rayon::join(
                    || Parsed::pieces(text, chunking.piece),
                    || more.then(|| read_block(&mut reader, &mut spare, chunking.block)),
                )
            },
        );
        if let Some(built) = built {
            emit(built)?;
        }
        let (ranges, pieces) = pieces;
        let text = std::mem::replace(&mut block, std::mem::take(&mut spare));
        if let Some(stitched) = parsed.replace(Parsed { text, ranges, pieces }) {
            spare = stitched.text;
        }
        let Some(next) = next else { break };
        input = next;
    }
    if let Some(mut last) = parsed {
        emit(stitcher.block(&mut last))?;
    }
    match input {
        Input::Failed(e) => Err(ImportError::Io { file: source.into(), source: e }),
        _ => {
            emit(stitcher.finish())?;
            Ok(degenerate_triangles)
        }
    }
}

/// A block's text and its pieces, parsed on their own, waiting to be
/// stitched.
pub(super) struct Parsed {
    pub(super) text: Vec<u8>,
    /// Where each piece lies in `text`.
    pub(super) ranges: Vec<Range<usize>>,
    pub(super) pieces: Vec<Piece>,
}

impl Parsed {
    /// Cuts `text` after newlines into pieces of about `size` bytes and
    /// parses them at once.
    fn pieces(text: &[u8], size: usize) -> (Vec<Range<usize>>, Vec<Piece>) {
        let size = size.max(1);
        let mut ranges = Vec::with_capacity(text.len() / size + 1);
        let mut start = 0;
        while start < text.len() {
            let end = match text.get(start + size - 1..).and_then(find_newline) {
                Some(newline) => start + size + newline,
                None => text.len(),
            };
            ranges.push(start..end);
            start = end;
        }
        let pieces = ranges.par_iter().map(|range| Piece::parse(&text[range.clone()], None)).collect();
        (ranges, pieces)
    }
}

/// What reading a block found after it.
enum Input {
    /// The block is full: more may follow.
    More,
    /// The input ended within the block.
    Ended,
    /// Reading failed after the bytes in the block.
    Failed(std::io::Error),
}

/// Appends up to `want` bytes of `reader` to `buffer`.
fn read_block<R: Read>(reader: &mut R, buffer: &mut Vec<u8>, want: usize) -> Input {
    buffer.reserve(want);
    // `read_to_end` retries interrupted reads and keeps what it read before
    // an error.
    match reader.by_ref().take(want as u64).read_to_end(buffer) {
        Ok(read) if read < want => Input::Ended,
        Ok(_) => Input::More,
        Err(e) => Input::Failed(e),
    }
}
