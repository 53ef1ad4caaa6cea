//! Wavefront OBJ export in mktree's scene form: `o NAME` per object, `v x y z`
//! in millimetres, `f a b c` with 1-based indices counted over the file.
//!
//! Coordinates are written as the shortest decimal that parses back to the
//! same f64, so import(export(scene)) is the same scene bit for bit.

use std::io::{self, Write};

use super::{Object, Scene};

/// Writes objects one at a time, so a generator can stream scenes larger
/// than memory.
pub struct ObjWriter<W: Write> {
    out: W,
    vertices_written: u64,
    objects_written: u64,
}

impl<W: Write> ObjWriter<W> {
    /// A writer that starts a new file on `out` (wrap files in a `BufWriter`).
    pub fn new(out: W) -> ObjWriter<W> {
        ObjWriter { out, vertices_written: 0, objects_written: 0 }
    }

    /// Writes a `#` comment line (the header of a generated scene).
    pub fn comment(&mut self, text: &str) -> io::Result<()> {
        for line in text.lines() {
            writeln!(self.out, "# {line}")?;
        }
        Ok(())
    }

    /// Appends one object; its id in the file is the number written before it.
    pub fn write_object(&mut self, object: &Object) -> io::Result<()> {
        // OBJ names end at the line's end; keep them on one line.
        let name: String = object.name.chars().map(|c| if c.is_control() { '_' } else { c }).collect();
        writeln!(self.out, "o {name}")?;
        for p in object.mesh.vertices() {
            writeln!(self.out, "v {} {} {}", p.x, p.y, p.z)?;
        }
        let base = self.vertices_written + 1;
        for t in object.mesh.triangles() {
            writeln!(
                self.out,
                "f {} {} {}",
                base + u64::from(t[0]),
                base + u64::from(t[1]),
                base + u64::from(t[2])
            )?;
        }
        self.vertices_written += object.mesh.vertex_count() as u64;
        self.objects_written += 1;
        Ok(())
    }

    /// Objects written so far.
    pub fn objects_written(&self) -> u64 {
        self.objects_written
    }

    /// Flushes and returns the underlying writer.
    pub fn finish(mut self) -> io::Result<W> {
        self.out.flush()?;
        Ok(self.out)
    }
}

/// Writes a whole scene as OBJ.
pub fn write_obj<W: Write>(scene: &Scene, out: W) -> io::Result<W> {
    let mut w = ObjWriter::new(out);
    for o in scene.objects() {
        w.write_object(o)?;
    }
    w.finish()
}
