//! BCF 3.0 export of a clash run (docs/clash.md, "BCF"; feature `bcf`):
//! one topic per group of clashes, with its status, a viewpoint whose
//! camera looks at the group's contact points, the group's objects as
//! the selected components (by IFC GlobalId when a key is one, else by
//! the key as the authoring tool's id), and a PNG snapshot drawn by the
//! library's renderer (A objects red, B objects blue). The archive holds
//! `bcf.version`, `extensions.xml` and a folder per topic named by its
//! GUID with `markup.bcf`, `viewpoint.bcfv` and `snapshot.png`
//! (buildingSMART's BCF-XML, release 3.0). Coordinates are metres.

use std::collections::{BTreeSet, HashSet};
use std::hash::{Hash, Hasher};

use super::ClashError;
use super::group::Group;
use super::key_json::key_text;
use super::status::Status;
use super::test::Clash;
use super::zip::ZipWriter;
use crate::db::ReadTransaction;
use crate::geom::{Aabb, Vector};
use crate::query::fetch_meshes;
use crate::render::{draw_meshes, framing};
use crate::scene::{Key, Mesh, ObjectId};

/// How an export is made.
#[derive(Debug, Clone, PartialEq)]
pub struct BcfOptions {
    /// The snapshot's width, pixels.
    pub width_px: u32,
    /// The snapshot's height, pixels.
    pub height_px: u32,
    /// Written as each topic's author.
    pub author: String,
    /// Written as each topic's creation date (`xs:dateTime`); `None`: now, UTC.
    pub date: Option<String>,
    /// A label on every topic (the test's name), if any.
    pub label: Option<String>,
}

impl Default for BcfOptions {
    fn default() -> BcfOptions {
        BcfOptions { width_px: 640, height_px: 480, author: "mktree".into(), date: None, label: None }
    }
}

/// The most topics an export writes (the ZIP has at most 65,535 entries, three per topic).
pub const MAX_TOPICS: usize = 20_000;

/// The colour of A objects in a snapshot (RGB).
pub const COLOUR_A: [u8; 3] = [214, 64, 56];
/// The colour of B objects in a snapshot (RGB).
pub const COLOUR_B: [u8; 3] = [72, 110, 190];

/// The BCF 3.0 archive of `clashes` (clashes, or a recorded run's tracked
/// clashes) grouped by `groups`, with their `statuses` (all New when
/// `None`), read from `txn` for the snapshots.
pub fn export_bcf<C: AsRef<Clash>>(
    txn: &ReadTransaction,
    clashes: &[C],
    statuses: Option<&[Status]>,
    groups: &[Group],
    opts: &BcfOptions,
) -> Result<Vec<u8>, ClashError> {
    if groups.len() > MAX_TOPICS {
        return Err(ClashError::Test(format!(
            "{} groups: a BCF export holds at most {MAX_TOPICS} topics",
            groups.len()
        )));
    }
    if statuses.is_some_and(|s| s.len() != clashes.len()) {
        return Err(ClashError::Test("one status per clash".into()));
    }
    if opts.width_px == 0 || opts.height_px == 0 || opts.width_px > 8192 || opts.height_px > 8192 {
        return Err(ClashError::Test("a snapshot of 1 to 8,192 pixels a side".into()));
    }
    let date = opts.date.clone().unwrap_or_else(now_utc);
    let mut zip = ZipWriter::default();
    let bad = |e: String| ClashError::Test(e);
    zip.add("bcf.version", VERSION_XML.as_bytes()).map_err(bad)?;
    zip.add("extensions.xml", extensions(opts.label.as_deref()).as_bytes()).map_err(bad)?;
    // Ids of the objects by key, from the key index.
    let entries = txn.key_entries(&mut crate::db::Reads::new(Some(txn.cache())))?;
    let id_of =
        |k: &Key| entries.binary_search_by(|e| e.key.cmp(k)).ok().map(|i| ObjectId(entries[i].object_id));
    for g in groups {
        let members: Vec<&Clash> =
            g.members.iter().filter_map(|&i| clashes.get(i)).map(AsRef::as_ref).collect();
        let Some(first) = members.first() else { continue };
        let status = statuses.and_then(|s| g.members.first().map(|&i| s[i])).unwrap_or(Status::New);
        let a_keys: BTreeSet<&Key> = members.iter().map(|c| &c.a).collect();
        let b_keys: BTreeSet<&Key> = members.iter().map(|c| &c.b).collect();
        let topic = guid(&("topic", &g.name, g.id, &a_keys, &b_keys));
        let viewpoint = guid(&("viewpoint", &topic));
        // The camera frames the contact points and a margin around them.
        let focus = members.iter().fold(Aabb::EMPTY, |b, c| {
            b.union(&c.overlap.unwrap_or(Aabb::new(c.point, c.point))).including(&c.point)
        });
        let margin = (focus.extent().norm() * 0.5).max(1000.0);
        let view = framing(&focus.grown(margin), opts.width_px, opts.height_px, 60.0);
        // The snapshot: the group's objects, A red and B blue.
        let ids: HashSet<ObjectId> = a_keys.iter().chain(&b_keys).filter_map(|k| id_of(k)).collect();
        let meshes = fetch_meshes(txn, ids)?;
        let coloured: Vec<(&Mesh, [u8; 3])> = a_keys
            .iter()
            .map(|k| (k, COLOUR_A))
            .chain(b_keys.iter().map(|k| (k, COLOUR_B)))
            .filter_map(|(k, c)| id_of(k).and_then(|id| meshes.get(&id)).map(|m| (m, c)))
            .collect();
        let img = draw_meshes(&view, &coloured).map_err(|e| ClashError::Query(e.into()))?;
        let png = png_bytes(img.width, img.height, &img.rgb)?;
        let title = format!(
            "{} {}: {} and {}{}",
            first.kind.name(),
            g.name,
            key_text(&first.a),
            key_text(&first.b),
            if members.len() > 1 { format!(" (+{} more)", members.len() - 1) } else { String::new() }
        );
        let mut description = String::new();
        for c in &members {
            let measure = match c.kind {
                super::test::ClashKind::Clearance => format!("distance {:.3} mm", c.distance),
                _ => format!("depth {:.3} mm", c.depth),
            };
            description.push_str(&format!(
                "{} {} / {}: {measure} at ({:.1}, {:.1}, {:.1}) mm. ",
                c.kind.name(),
                key_text(&c.a),
                key_text(&c.b),
                c.point.x,
                c.point.y,
                c.point.z
            ));
        }
        let markup = markup(&topic, &viewpoint, status, &title, description.trim_end(), &date, opts);
        let forward = (view.target - view.eye).normalize();
        let right = forward.cross(&Vector::z()).try_normalize(1e-12).unwrap_or(Vector::x());
        let up = right.cross(&forward);
        let components: Vec<&Key> =
            a_keys.iter().chain(&b_keys).copied().collect::<BTreeSet<_>>().into_iter().collect();
        let vis = visinfo(&viewpoint, &components, view.eye.coords / 1000.0, forward, up, 60.0, opts);
        zip.add(&format!("{topic}/markup.bcf"), markup.as_bytes()).map_err(bad)?;
        zip.add(&format!("{topic}/viewpoint.bcfv"), vis.as_bytes()).map_err(bad)?;
        zip.add(&format!("{topic}/snapshot.png"), &png).map_err(bad)?;
    }
    zip.finish().map_err(bad)
}

const VERSION_XML: &str = "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<Version VersionId=\"3.0\" />\n";

/// The statuses a topic may carry.
const STATUSES: [Status; 5] =
    [Status::New, Status::Active, Status::Reviewed, Status::Approved, Status::Resolved];

fn status_name(s: Status) -> &'static str {
    match s {
        Status::New => "New",
        Status::Active => "Active",
        Status::Reviewed => "Reviewed",
        Status::Approved => "Approved",
        Status::Resolved => "Resolved",
    }
}

fn extensions(label: Option<&str>) -> String {
    let mut s = String::from(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<Extensions>\n  <TopicTypes>\n    <TopicType>Clash</TopicType>\n  </TopicTypes>\n  <TopicStatuses>\n",
    );
    for st in STATUSES {
        s.push_str(&format!("    <TopicStatus>{}</TopicStatus>\n", status_name(st)));
    }
    s.push_str("  </TopicStatuses>\n  <TopicLabels>\n");
    for l in ["hard", "clearance", "touch", "duplicate"]
        .iter()
        .map(|s| s.to_string())
        .chain(label.map(str::to_string))
    {
        s.push_str(&format!("    <TopicLabel>{}</TopicLabel>\n", escape(&l)));
    }
    s.push_str("  </TopicLabels>\n</Extensions>\n");
    s
}

fn markup(
    topic: &str,
    viewpoint: &str,
    status: Status,
    title: &str,
    description: &str,
    date: &str,
    opts: &BcfOptions,
) -> String {
    let kind = title.split(' ').next().unwrap_or("hard");
    let mut labels = format!("      <Label>{}</Label>\n", escape(kind));
    if let Some(l) = &opts.label {
        labels.push_str(&format!("      <Label>{}</Label>\n", escape(l)));
    }
    format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<Markup>\n  <Topic Guid=\"{topic}\" TopicType=\"Clash\" TopicStatus=\"{}\">\n    <Title>{}</Title>\n    <Labels>\n{labels}    </Labels>\n    <CreationDate>{}</CreationDate>\n    <CreationAuthor>{}</CreationAuthor>\n    <Description>{}</Description>\n    <Viewpoints>\n      <ViewPoint Guid=\"{viewpoint}\">\n        <Viewpoint>viewpoint.bcfv</Viewpoint>\n        <Snapshot>snapshot.png</Snapshot>\n      </ViewPoint>\n    </Viewpoints>\n  </Topic>\n</Markup>\n",
        status_name(status),
        escape(title),
        escape(date),
        escape(if opts.author.trim().is_empty() { "mktree" } else { &opts.author }),
        escape(if description.is_empty() { "-" } else { description }),
    )
}

/// An IFC GlobalId: 22 characters of IFC's base-64 alphabet.
fn is_global_id(k: &Key) -> bool {
    match k {
        Key::Bytes(b) => {
            b.len() == 22 && b.iter().all(|&c| c.is_ascii_alphanumeric() || c == b'_' || c == b'$')
        }
        Key::Int(_) => false,
    }
}

fn visinfo(
    guid: &str,
    components: &[&Key],
    eye_m: Vector,
    forward: Vector,
    up: Vector,
    fov_deg: f64,
    opts: &BcfOptions,
) -> String {
    let xyz = |name: &str, v: Vector| {
        format!(
            "      <{name}>\n        <X>{}</X>\n        <Y>{}</Y>\n        <Z>{}</Z>\n      </{name}>\n",
            v.x, v.y, v.z
        )
    };
    let mut s = format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<VisualizationInfo Guid=\"{guid}\">\n  <Components>\n    <Selection>\n"
    );
    for k in components {
        if is_global_id(k) {
            s.push_str(&format!("      <Component IfcGuid=\"{}\" />\n", escape(&key_text(k))));
        } else {
            s.push_str(&format!(
                "      <Component>\n        <OriginatingSystem>mktree</OriginatingSystem>\n        <AuthoringToolId>{}</AuthoringToolId>\n      </Component>\n",
                escape(&key_text(k))
            ));
        }
    }
    s.push_str("    </Selection>\n  </Components>\n  <PerspectiveCamera>\n");
    s.push_str(&xyz("CameraViewPoint", eye_m));
    s.push_str(&xyz("CameraDirection", forward));
    s.push_str(&xyz("CameraUpVector", up));
    s.push_str(&format!(
        "    <FieldOfView>{fov_deg}</FieldOfView>\n    <AspectRatio>{}</AspectRatio>\n  </PerspectiveCamera>\n</VisualizationInfo>\n",
        f64::from(opts.width_px) / f64::from(opts.height_px)
    ));
    s
}

/// Text as XML character data or an attribute value: the five special
/// characters escaped, characters XML 1.0 does not allow replaced.
pub(crate) fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            '\t' | '\n' | '\r' => out.push(c),
            c if (c as u32) < 0x20 || c == '\u{FFFE}' || c == '\u{FFFF}' => out.push('\u{FFFD}'),
            c => out.push(c),
        }
    }
    out
}

/// A GUID in BCF's form (lowercase 8-4-4-4-12 hex), from a hash of `x`:
/// the same export gives the same GUIDs.
fn guid(x: &impl Hash) -> String {
    let half = |salt: u64| {
        let mut h = std::collections::hash_map::DefaultHasher::new();
        salt.hash(&mut h);
        x.hash(&mut h);
        h.finish()
    };
    let (a, b) = (half(1), half(2));
    // Version 4 and variant bits, as a random UUID has them.
    let a = (a & !0xF000) | 0x4000;
    let b = (b & !(0xC << 60)) | (0x8 << 60);
    format!(
        "{:08x}-{:04x}-{:04x}-{:04x}-{:012x}",
        a >> 32,
        (a >> 16) & 0xFFFF,
        a & 0xFFFF,
        b >> 48,
        b & 0xFFFF_FFFF_FFFF
    )
}

/// The PNG of an RGB picture.
fn png_bytes(width: u32, height: u32, rgb: &[u8]) -> Result<Vec<u8>, ClashError> {
    let mut out = Vec::new();
    let mut enc = png::Encoder::new(&mut out, width, height);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let fail = |e: png::EncodingError| ClashError::Test(format!("the snapshot's PNG: {e}"));
    let mut w = enc.write_header().map_err(fail)?;
    w.write_image_data(rgb).map_err(fail)?;
    w.finish().map_err(fail)?;
    Ok(out)
}

/// Now, UTC, as `xs:dateTime` (`2026-11-27T12:00:00Z`).
fn now_utc() -> String {
    let secs = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_secs());
    let (days, rem) = (secs / 86_400, secs % 86_400);
    // Howard Hinnant's civil_from_days.
    let z = days as i64 + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!("{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}Z", rem / 3600, rem % 3600 / 60, rem % 60)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn guids_have_bcf_form_and_escapes_are_xml() {
        let g = guid(&("x", 1));
        assert_eq!(g.len(), 36);
        assert!(g.chars().all(|c| c == '-' || c.is_ascii_hexdigit() && !c.is_ascii_uppercase()));
        assert_eq!(g, guid(&("x", 1)));
        assert_ne!(g, guid(&("x", 2)));
        assert_eq!(escape("a<b & \"c\"\u{1}"), "a&lt;b &amp; &quot;c&quot;\u{FFFD}");
        assert!(is_global_id(&Key::bytes("2O2Fr$t4X7Zf8NOew3FLOH").unwrap()));
        assert!(!is_global_id(&Key::bytes("PIPE-1").unwrap()) && !is_global_id(&Key::Int(5)));
        let now = now_utc();
        assert_eq!(now.len(), 20, "{now}");
        assert!(now.starts_with("20"));
    }
}
