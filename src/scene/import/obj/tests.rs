use super::number::{leading_digits, scan_f64, scan_index, short_index};
use super::statement::find_newline;
use super::*;
use crate::geom::Point;
use proptest::prelude::*;

fn read(text: &str) -> Result<Imported, ImportError> {
    read_obj(text.as_bytes(), Path::new("dir/test.obj"))
}

fn summary(imported: &Imported) -> Vec<(String, usize, usize)> {
    imported
        .scene
        .objects()
        .iter()
        .map(|o| (o.name.clone(), o.mesh.vertex_count(), o.mesh.triangle_count()))
        .collect()
}

fn owned(rows: &[(&str, usize, usize)]) -> Vec<(String, usize, usize)> {
    rows.iter().map(|&(n, v, t)| (n.to_string(), v, t)).collect()
}

const SQUARE: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n";

#[test]
fn o_lines_start_objects_and_g_lines_are_then_ignored() {
    let text = format!("{SQUARE}f 1 2 3\no a\ng x\nf 1 2 3 4\no b c \ng y\nf -1 -2 -3\n");
    let imported = read(&text).unwrap();
    assert_eq!(summary(&imported), owned(&[("test", 3, 1), ("a", 4, 2), ("b c", 3, 1)]));
}

#[test]
fn g_lines_start_objects_in_a_file_without_o() {
    let text = format!("g default\n{SQUARE}f 1 2 3\ng left\nf 1 2 3\ng empty\ng right\nf 2 3 4\n");
    let imported = read(&text).unwrap();
    assert_eq!(summary(&imported), owned(&[("default", 3, 1), ("left", 3, 1), ("right", 3, 1)]));
}

#[test]
fn an_o_after_groups_merges_the_groups_into_the_file_object() {
    let text = format!("{SQUARE}g a\nf 1 2 3\ng b\nf 2 3 4\no real\nf 1 3 4\n");
    let imported = read(&text).unwrap();
    assert_eq!(summary(&imported), owned(&[("test", 4, 2), ("real", 3, 1)]));
}

#[test]
fn corners_with_texture_and_normal_indices_use_the_position() {
    let text = format!("{SQUARE}vt 0 0\nvn 0 0 1\nusemtl steel\ns 1\nl 1 2\nf 1/1/1 2//1 3/1 4/1/1\n");
    let imported = read(&text).unwrap();
    assert_eq!(imported.scene.objects()[0].mesh.triangles(), &[[0, 1, 2], [0, 2, 3]]);
}

#[test]
fn object_vertices_are_the_used_ones_in_file_order() {
    // Faces name vertices 4, 2 and 3 (1-based) out of order; 1 is unused.
    let text = "v 9 9 9\nv 1 0 0\nv 0 1 0\nv 0 0 1\no t\nf 4 2 3\n";
    let imported = read(text).unwrap();
    let mesh = &imported.scene.objects()[0].mesh;
    assert_eq!(mesh.triangles(), &[[2, 0, 1]]);
    assert_eq!(mesh.vertex(0), Point::new(1.0, 0.0, 0.0));
}

#[test]
fn scattered_vertices_are_renumbered_by_sorting() {
    let mut text = String::from("v 0 0 0\nv 1 0 0\n");
    for i in 0..5000 {
        text.push_str(&format!("v {i} 5 0\n"));
    }
    text.push_str("v 0 1 0\no far\nf 1 2 -1\n");
    let imported = read(&text).unwrap();
    let mesh = &imported.scene.objects()[0].mesh;
    assert_eq!(mesh.triangles(), &[[0, 1, 2]]);
    assert_eq!(mesh.vertex(2), Point::new(0.0, 1.0, 0.0));
}

#[test]
fn degenerate_triangles_are_kept_and_counted() {
    let text = format!("{SQUARE}f 1 1 2\nf 1 2 3\n");
    let imported = read(&text).unwrap();
    assert_eq!((imported.scene.triangle_count(), imported.degenerate_triangles), (2, 1));
}

#[test]
fn crlf_tabs_and_comments_are_accepted() {
    let text = "# header\r\n\r\no\tpart one \r\nv 0 0 0 1\r\nv\t1 0 0\r\nv 0 1 0\r\nf 1 2 3 # tri\r\n";
    let imported = read(text).unwrap();
    assert_eq!(summary(&imported), owned(&[("part one", 3, 1)]));
}

#[test]
fn each_error_names_the_line() {
    let cases: [(&str, &str); 8] = [
        ("v 1 2\n", "test.obj: line 1: expected 3 coordinates after `v`"),
        ("v 1 2 x\n", "line 1: expected a number, found \"x\""),
        ("v 0 0 0\nv nan 0 0\n", "line 2: object \"test\" has a NaN or infinite coordinate"),
        ("v 0 0 1e999\n", "line 1: object \"test\" has a NaN or infinite coordinate"),
        ("v 0 0 0\no p\nf 1 1 2\n", "line 3: object \"p\": vertex index 2 is out of range (1 vertices)"),
        ("v 0 0 0\nf 1 1 -2\n", "vertex index -2 is out of range"),
        ("v 0 0 0\nf 0 1 1\n", "vertex index 0 is out of range"),
        ("v 0 0 0\nf 1 1\n", "line 2: expected at least 3 vertex indices after `f`"),
    ];
    for (text, message) in cases {
        let err = read(text).unwrap_err().to_string();
        assert!(err.contains(message), "{text:?}: {err}");
    }
    let err = read(&format!("{SQUARE}f 1 x/2 3\n")).unwrap_err();
    assert!(err.to_string().contains("line 5: expected a vertex index"), "{err}");
}

#[test]
fn an_o_without_faces_is_refused_with_its_line() {
    let err = read(&format!("{SQUARE}o full\nf 1 2 3\no hollow\no next\nf 1 2 3\n")).unwrap_err();
    assert_eq!(err.to_string(), "dir/test.obj: object \"hollow\" (line 7) has no triangles");
    let err = read(&format!("{SQUARE}o last\n")).unwrap_err();
    assert!(err.to_string().contains("\"last\" (line 5)"), "{err}");
}

#[test]
fn a_file_without_faces_is_an_empty_scene() {
    for text in ["", "# nothing\n", SQUARE, "g a\ng b\n"] {
        let err = read(text).unwrap_err();
        assert!(matches!(err, ImportError::EmptyScene { .. }), "{text:?}: {err}");
    }
}

#[test]
fn a_whole_file_is_one_object_named_by_its_stem() {
    let text = format!("{SQUARE}o a\nf 1 2 3\ng b\nf 1 3 4\n");
    let (object, _) = read_obj_as_one_object(text.as_bytes(), Path::new("d/pump.obj")).unwrap();
    assert_eq!((object.name.as_str(), object.mesh.triangle_count()), ("pump", 2));
    let err = read_obj_as_one_object(SQUARE.as_bytes(), Path::new("d/pump.obj")).unwrap_err();
    assert_eq!(err.to_string(), "d/pump.obj: object \"pump\" has no triangles");
}

/// A whole token as a number, as the parser reads it: at the end of
/// the text, and before a blank (the short forms' path), which agree.
fn parse_f64(token: &[u8]) -> Option<f64> {
    let at_end = scan_f64(token).filter(|(_, rest)| rest.is_empty()).map(|(value, _)| value);
    let line = [token, b" 1"].concat();
    let in_line = scan_f64(&line).filter(|(_, rest)| *rest == b" 1").map(|(value, _)| value);
    assert_eq!(at_end.map(f64::to_bits), in_line.map(f64::to_bits), "{}", String::from_utf8_lossy(token));
    at_end
}

fn parse_i64(token: &[u8]) -> Option<i64> {
    let at_end = scan_index(token).filter(|(_, rest)| rest.is_empty()).map(|(value, _)| value);
    let line = [token, b" 1"].concat();
    let in_line = short_index(&line).or_else(|| scan_index(&line));
    assert_eq!(at_end, in_line.filter(|(_, rest)| *rest == b" 1").map(|(value, _)| value));
    at_end
}

#[test]
fn digit_runs_of_every_length_stop_at_any_non_digit() {
    for length in 0..=20 {
        let digits: String = (0..length).map(|i| char::from(b'0' + (i * 7 % 10) as u8)).collect();
        for stop in [b' ', b'.', b'/', b'e', 0xff, 0x80, 0xba, b'9' + 1, b'0' - 1] {
            let mut bytes = digits.clone().into_bytes();
            bytes.push(stop);
            bytes.extend_from_slice(b"123");
            let (value, count, rest) = leading_digits(&bytes, 0);
            assert_eq!((count, rest[0]), (length, stop), "{digits} then {stop}");
            if length <= 19 {
                assert_eq!(value, digits.parse::<u64>().unwrap_or(0), "{digits} then {stop}");
            }
        }
        let (value, count, rest) = leading_digits(digits.as_bytes(), 7);
        assert_eq!((count, rest.len()), (length, 0));
        if length <= 18 {
            assert_eq!(value, format!("7{digits}").parse::<u64>().unwrap());
        }
    }
}

#[test]
fn newlines_are_found_at_every_offset() {
    for length in 0..40 {
        let mut bytes = vec![b'x'; length];
        assert_eq!(find_newline(&bytes), None);
        for at in 0..length {
            bytes[at] = b'\n';
            assert_eq!(find_newline(&bytes), Some(at), "{length} {at}");
            bytes[at] = 0x8A;
        }
    }
}

#[test]
fn lines_cut_by_the_reader_buffer_are_joined() {
    let text = format!("{SQUARE}o cut here\nf 1 2 3\nf 1 3 4");
    for capacity in [1, 2, 3, 7, 64] {
        let reader = std::io::BufReader::with_capacity(capacity, text.as_bytes());
        let imported = read_obj(reader, Path::new("cut.obj")).unwrap();
        assert_eq!(summary(&imported), owned(&[("cut here", 4, 2)]), "capacity {capacity}");
    }
}

/// A reader that fails after `good` bytes, some reads interrupted.
struct Failing<'a> {
    text: &'a [u8],
    good: usize,
    reads: usize,
}

impl std::io::Read for Failing<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        self.reads += 1;
        if self.reads.is_multiple_of(3) {
            return Err(std::io::ErrorKind::Interrupted.into());
        }
        if self.good == 0 {
            return Err(std::io::Error::other("disk on fire"));
        }
        let n = buf.len().min(self.good).min(self.text.len()).min(5);
        buf[..n].copy_from_slice(&self.text[..n]);
        (self.text, self.good) = (&self.text[n..], self.good - n);
        Ok(n)
    }
}

#[test]
fn a_failed_read_ends_the_file_after_the_lines_before_it() {
    // The read fails after line 5 or inside line 7: line 5's own error
    // (a bad index) comes first, as it did line by line.
    let text = format!("{SQUARE}f 1 2 9\no p\nf 1 2 3\n");
    for (good, chunking) in
        [(40, Chunking { block: 3, piece: 2 }), (40, Chunking::DEFAULT), (49, Chunking::DEFAULT)]
    {
        let reader = Failing { text: text.as_bytes(), good, reads: 0 };
        let mut objects = Vec::new();
        let ours =
            parse(reader, Path::new("f.obj"), Grouping::ByObjectLines, chunking, Vertices::default(), |o| {
                objects.push(o)
            });
        let old = oracle::read_obj(
            std::io::BufReader::with_capacity(4, Failing { text: text.as_bytes(), good, reads: 0 }),
            Path::new("f.obj"),
        );
        let (ours, old) = (ours.unwrap_err().to_string(), old.unwrap_err().to_string());
        assert_eq!(ours, old, "{good} bytes");
        assert!(ours.contains("line 5"), "{ours}");
    }
    let reader = Failing { text: SQUARE.as_bytes(), good: 10, reads: 0 };
    let err = read_obj(reader, Path::new("f.obj")).unwrap_err();
    assert!(matches!(err, ImportError::Io { .. }), "{err}");
}

#[test]
fn numbers_end_at_whitespace() {
    assert_eq!(scan_f64(b"1.5 2").map(|(v, rest)| (v, rest.len())), Some((1.5, 2)));
    assert_eq!(scan_f64(b"1e3\t2").map(|(v, rest)| (v, rest.len())), Some((1000.0, 2)));
    assert_eq!(scan_index(b"7/1/2 8").map(|(v, rest)| (v, rest.len())), Some((7, 2)));
    assert_eq!(scan_index(b"-7//2").map(|(v, rest)| (v, rest.len())), Some((-7, 0)));
    assert_eq!(scan_index(b"7x 8"), None);
    assert_eq!(scan_index(b"/7"), None);
}

#[test]
fn integers_are_parsed_with_sign_and_overflow_checks() {
    assert_eq!(parse_i64(b"42"), Some(42));
    assert_eq!(parse_i64(b"-7"), Some(-7));
    assert_eq!(parse_i64(b"+7"), Some(7));
    assert_eq!(parse_i64(b"-"), None);
    assert_eq!(parse_i64(b""), None);
    assert_eq!(parse_i64(b"1234567890123456789"), None);
    assert_eq!(parse_i64(b"-123456789012345678"), Some(-123_456_789_012_345_678));
    assert_eq!(parse_i64(b"1a"), None);
}

#[test]
fn decimals_that_std_refuses_are_refused() {
    for bad in
        ["", "-", ".", "1..2", "1.2.3", "--1", "1-", "0x10", "1,5", "12345678.9a", "1234567/", ":2345678"]
    {
        assert_eq!(parse_f64(bad.as_bytes()), None, "{bad:?}");
    }
    assert_eq!(parse_f64(b"-0").map(f64::is_sign_negative), Some(true));
}

/// Everything a parse gives: the objects and the zero-area count, or
/// the error as printed and as built.
fn outcome(text: &[u8], grouping: Grouping, chunking: Chunking) -> Result<(Vec<Object>, usize), String> {
    outcome_over(text, grouping, chunking, Vertices::default())
}

/// [`outcome`] with every vertex run but the newest in a spill file.
fn outcome_spilled(
    text: &[u8],
    grouping: Grouping,
    chunking: Chunking,
) -> Result<(Vec<Object>, usize), String> {
    let spill = SpillFile::create_in(&std::env::temp_dir(), "test-vertices").map_err(|e| e.to_string())?;
    outcome_over(text, grouping, chunking, Vertices::spilling(spill, 0))
}

fn outcome_over(
    text: &[u8],
    grouping: Grouping,
    chunking: Chunking,
    vertices: Vertices,
) -> Result<(Vec<Object>, usize), String> {
    let mut objects = Vec::new();
    parse(text, Path::new("cut/test.obj"), grouping, chunking, vertices, |object| objects.push(object))
        .map(|degenerate| (objects, degenerate))
        .map_err(|e| format!("{e} / {e:?}"))
}

/// A random OBJ line, its indices still as shares of the vertices
/// before it: mostly valid, with every statement, index form and fault
/// the parser tells apart.
#[derive(Debug, Clone)]
enum Line {
    Vertex {
        xyz: Vec<String>,
        separator: &'static str,
    },
    /// Each corner: `Ok((from the end, share, suffix))` or a raw token.
    Face {
        corners: Vec<Result<(bool, f64, &'static str), &'static str>>,
        separator: &'static str,
        comment: bool,
    },
    Header {
        keyword: &'static str,
        separator: &'static str,
        name: &'static str,
    },
    Other(&'static str),
}

fn obj_line() -> impl Strategy<Value = Line> {
    let number = prop_oneof![
        200 => (-3i32..40).prop_map(|i| i.to_string()),
        100 => (-40_000i32..40_000).prop_map(|i| format!("{}", f64::from(i) / 16.0)),
        2 => prop::sample::select(vec!["1e3", "-0", "+2.5", ".5", "7."]).prop_map(String::from),
        1 => prop::sample::select(vec!["nan", "1e999", "x", "1..2", "-inf", "1e400"]).prop_map(String::from),
    ];
    let corner = prop_oneof![
        200 => (prop::bool::weighted(0.3), 0.0..1.0f64, prop::sample::select(vec!["", "", "/1", "//2", "/3/1"]))
            .prop_map(Ok),
        1 => prop::sample::select(vec!["0", "x", "4294967297", "-99999999999", "1/x", "99", "-99"]).prop_map(Err),
    ];
    let separator = prop::sample::select(vec![" ", " ", " ", "  ", "\t", " \t"]);
    prop_oneof![
        10 => (prop::collection::vec(number, 3..=4), separator.clone())
            .prop_map(|(xyz, separator)| Line::Vertex { xyz, separator }),
        8 => (prop::collection::vec(corner, 3..=6), separator.clone(), prop::bool::weighted(0.1))
            .prop_map(|(corners, separator, comment)| Line::Face { corners, separator, comment }),
        2 => (
            prop::sample::select(vec!["o", "o", "g", "g", " o", "g\t"]),
            separator,
            prop::sample::select(vec!["", "a", "b c", "a", "pipe 1", "ü"]),
        )
            .prop_map(|(keyword, separator, name)| Line::Header { keyword, separator, name }),
        1 => prop::sample::select(vec![
            "", "# note", "vt 0 0", "vn 0 0 1", "s 1", "usemtl m", "  ", "v", "f", "v 1 2", "f 1 2", "l 1 2"
        ])
        .prop_map(Line::Other),
    ]
}

/// OBJ text from random lines: indices become numbers of vertices
/// defined before their line (a few reach past them).
fn obj_text() -> impl Strategy<Value = String> {
    (0..8usize, prop::collection::vec(obj_line(), 0..80), prop::bool::ANY, prop::bool::ANY).prop_map(
        |(first_vertices, lines, crlf, final_newline)| {
            // Most files define vertices before their first face.
            let first =
                (0..first_vertices).map(|i| Line::Vertex { xyz: vec![i.to_string(); 3], separator: " " });
            let mut vertices = 0;
            let rendered: Vec<String> = first
                .chain(lines)
                .map(|line| match line {
                    Line::Vertex { xyz, separator } => {
                        vertices += 1;
                        format!("v{separator}{}", xyz.join(separator))
                    }
                    Line::Face { corners, separator, comment } => {
                        let corners: Vec<String> = corners
                            .into_iter()
                            .map(|c| match c {
                                Ok((back, share, suffix)) => {
                                    // One past the vertices now and then.
                                    let n = (share * (vertices as f64 + 0.02)) as i64 + 1;
                                    format!("{}{n}{suffix}", if back { "-" } else { "" })
                                }
                                Err(raw) => raw.to_string(),
                            })
                            .collect();
                        format!(
                            "f{separator}{}{}",
                            corners.join(separator),
                            if comment { " # c" } else { "" }
                        )
                    }
                    Line::Header { keyword, separator, name } => format!("{keyword}{separator}{name}"),
                    Line::Other(text) => text.to_string(),
                })
                .collect();
            let mut text = rendered.join(if crlf { "\r\n" } else { "\n" });
            if final_newline && !text.is_empty() {
                text.push('\n');
            }
            text
        },
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(30000))]

    /// The sequential parser's result, whatever the cut: blocks and
    /// pieces of a few bytes end inside lines, between `\r` and `\n`,
    /// and around `o`/`g` lines.
    #[test]
    fn any_cut_of_the_input_gives_the_sequential_result(
        text in obj_text(),
        block in 1usize..48,
        piece in 1usize..24,
        whole_file in prop::bool::ANY,
    ) {
        let source = Path::new("cut/test.obj");
        let expected = if whole_file {
            oracle::read_obj_as_one_object(text.as_bytes(), source).map(|(object, d)| (vec![object], d))
        } else {
            match oracle::read_obj(text.as_bytes(), source) {
                // `parse` leaves an empty scene to its callers.
                Err(ImportError::EmptyScene { .. }) => Ok((Vec::new(), 0)),
                old => old.map(|imported| (imported.scene.into_objects(), imported.degenerate_triangles)),
            }
        };
        let expected = expected.map_err(|e| format!("{e} / {e:?}"));
        let grouping = if whole_file { Grouping::WholeFile } else { Grouping::ByObjectLines };
        prop_assert_eq!(outcome(text.as_bytes(), grouping, Chunking { block, piece }), expected.clone());
        // Vertices read back from a spill file, run by run.
        prop_assert_eq!(outcome_spilled(text.as_bytes(), grouping, Chunking { block, piece }), expected.clone());
        prop_assert_eq!(outcome(text.as_bytes(), grouping, Chunking::DEFAULT), expected);
    }
}

proptest! {
    #[test]
    fn digit_runs_parse_as_std_does(text in "[-+]?[0-9]{0,20}(\\.[0-9]{0,20})?") {
        let std: Option<f64> = text.parse().ok();
        prop_assert_eq!(parse_f64(text.as_bytes()).map(f64::to_bits), std.map(f64::to_bits), "{}", text);
        // parse_i64 takes up to 18 digits.
        if text.trim_start_matches(['-', '+']).len() <= 18 {
            prop_assert_eq!(parse_i64(text.as_bytes()), text.parse().ok());
        }
    }

    #[test]
    fn long_decimals_round_exactly_as_std_does(digits in 1u64..10_000_000_000_000_000_000, k in 0usize..=22) {
        let text = format!("{digits}");
        let text = if k >= text.len() { format!("0.{}{text}", "0".repeat(k - text.len())) } else {
            format!("{}.{}", &text[..text.len() - k], &text[text.len() - k..])
        };
        let std: f64 = text.parse().unwrap();
        prop_assert_eq!(parse_f64(text.as_bytes()).map(f64::to_bits), Some(std.to_bits()), "{}", text);
    }

    #[test]
    fn decimals_parse_exactly_as_std_does(
        x in prop_oneof![any::<f64>(), -1.0e7f64..1.0e7, (-100_000i64..100_000).prop_map(|i| i as f64 / 1000.0)],
        digits in 0usize..8,
    ) {
        for text in [format!("{x}"), format!("{x:.digits$}"), format!("{x:e}")] {
            let std: Option<f64> = text.parse().ok();
            let ours = parse_f64(text.as_bytes());
            prop_assert_eq!(ours.map(f64::to_bits), std.map(f64::to_bits), "{}", text);
        }
    }
}
