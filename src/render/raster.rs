//! A small software rasterizer: triangles in world coordinates (mm) seen by
//! a [`View`], drawn with a z-buffer and flat shading into an RGB image.
//! No GPU and no font: the pictures of a cut (`draw.rs`) and the tests that
//! count their pixels need nothing more.
//!
//! Projection: a point at camera coordinates (x right, y up, z along the
//! view direction) lands at pixel (w/2 + f x/z, h/2 - f y/z), f the view's
//! focal length in pixels, the same f the view query's projected errors use.
//! Triangles are clipped to the near plane; depth is tested on 1/z, which is
//! linear in screen space. Both sides of a triangle are drawn (scenes hold
//! open meshes), shaded by the cosine between its normal and the view
//! direction (a headlight).

use crate::geom::{Point, Vector};
use crate::query::View;

/// An RGB picture with its depth buffer.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// Row by row from the top, 3 bytes a pixel.
    pub rgb: Vec<u8>,
    /// 1/z of the nearest surface drawn at each pixel; 0 where none is.
    inverse_depth: Vec<f32>,
}

/// The background: white.
pub const BACKGROUND: [u8; 3] = [255, 255, 255];

impl Image {
    /// A blank picture.
    pub fn new(width: u32, height: u32) -> Image {
        let n = width as usize * height as usize;
        Image { width, height, rgb: BACKGROUND.repeat(n), inverse_depth: vec![0.0; n] }
    }

    /// True when a surface was drawn at pixel (x, y) (false outside).
    pub fn drawn(&self, x: u32, y: u32) -> bool {
        x < self.width && y < self.height && self.inverse_depth[(y * self.width + x) as usize] > 0.0
    }

    /// Pixels a surface was drawn at.
    pub fn coverage(&self) -> u64 {
        self.inverse_depth.iter().filter(|&&d| d > 0.0).count() as u64
    }

    /// The colour at pixel (x, y); `None` outside.
    pub fn pixel(&self, x: u32, y: u32) -> Option<[u8; 3]> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let i = 3 * (y * self.width + x) as usize;
        Some([self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]])
    }
}

/// A view's camera frame, to project world points.
pub(crate) struct Projector {
    eye: Point,
    right: Vector,
    up: Vector,
    forward: Vector,
    focal: f64,
    near: f64,
    far: f64,
    half: (f64, f64),
}

impl Projector {
    /// The frame of `view`; `None` when the view direction is vertical or
    /// null (up is +z), as [`crate::geom::Frustum::from_camera`] refuses.
    pub(crate) fn new(view: &View) -> Option<Projector> {
        let forward = (view.target - view.eye).try_normalize(0.0)?;
        let right = forward.cross(&Vector::z()).try_normalize(1e-12)?;
        let up = right.cross(&forward);
        Some(Projector {
            eye: view.eye,
            right,
            up,
            forward,
            focal: view.focal_px(),
            near: view.near_mm,
            far: view.far_mm,
            half: (f64::from(view.width_px) / 2.0, f64::from(view.height_px) / 2.0),
        })
    }

    fn camera(&self, p: &Point) -> Vector {
        let d = p - self.eye;
        Vector::new(d.dot(&self.right), d.dot(&self.up), d.dot(&self.forward))
    }

    /// Draws triangle `t` in `colour`, shaded by its facing.
    pub(crate) fn triangle(&self, img: &mut Image, t: &[Point; 3], colour: [u8; 3]) {
        let n = (t[1] - t[0]).cross(&(t[2] - t[0]));
        let Some(n) = n.try_normalize(0.0) else { return };
        let shade = 0.35 + 0.65 * n.dot(&self.forward).abs();
        let c = colour.map(|v| (f64::from(v) * shade).round().clamp(0.0, 255.0) as u8);
        let cam = t.map(|p| self.camera(&p));
        // Clipped to z >= near: a polygon of up to 4 corners.
        let mut poly: Vec<Vector> = Vec::with_capacity(4);
        for i in 0..3 {
            let (a, b) = (cam[i], cam[(i + 1) % 3]);
            let (ina, inb) = (a.z >= self.near, b.z >= self.near);
            if ina {
                poly.push(a);
            }
            if ina != inb {
                poly.push(a + (b - a) * ((self.near - a.z) / (b.z - a.z)));
            }
        }
        if poly.len() < 3 {
            return;
        }
        let screen: Vec<(f64, f64, f64)> = poly
            .iter()
            .map(|v| (self.half.0 + self.focal * v.x / v.z, self.half.1 - self.focal * v.y / v.z, 1.0 / v.z))
            .collect();
        for i in 1..screen.len() - 1 {
            self.fill(img, [screen[0], screen[i], screen[i + 1]], c);
        }
    }

    /// Fills a screen triangle of (x, y, 1/z) corners: the pixels whose
    /// centres it holds (edges included), nearer than what is drawn there.
    fn fill(&self, img: &mut Image, s: [(f64, f64, f64); 3], c: [u8; 3]) {
        let area = (s[1].0 - s[0].0) * (s[2].1 - s[0].1) - (s[2].0 - s[0].0) * (s[1].1 - s[0].1);
        if area == 0.0 || !area.is_finite() {
            return;
        }
        let (w, h) = (f64::from(img.width), f64::from(img.height));
        let lo_x = s.iter().map(|p| p.0).fold(f64::INFINITY, f64::min).floor().max(0.0);
        let hi_x = s.iter().map(|p| p.0).fold(f64::NEG_INFINITY, f64::max).ceil().min(w);
        let lo_y = s.iter().map(|p| p.1).fold(f64::INFINITY, f64::min).floor().max(0.0);
        let hi_y = s.iter().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max).ceil().min(h);
        if lo_x >= hi_x || lo_y >= hi_y {
            return;
        }
        let min_inverse = 1.0 / self.far;
        for y in lo_y as u32..hi_y as u32 {
            let py = f64::from(y) + 0.5;
            for x in lo_x as u32..hi_x as u32 {
                let px = f64::from(x) + 0.5;
                let edge = |a: (f64, f64, f64), b: (f64, f64, f64)| {
                    (b.0 - a.0) * (py - a.1) - (b.1 - a.1) * (px - a.0)
                };
                let (w0, w1, w2) =
                    (edge(s[1], s[2]) / area, edge(s[2], s[0]) / area, edge(s[0], s[1]) / area);
                if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                    continue;
                }
                let inverse = w0 * s[0].2 + w1 * s[1].2 + w2 * s[2].2;
                let i = (y * img.width + x) as usize;
                if inverse < min_inverse || inverse as f32 <= img.inverse_depth[i] {
                    continue;
                }
                img.inverse_depth[i] = inverse as f32;
                img.rgb[3 * i..3 * i + 3].copy_from_slice(&c);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn view() -> View {
        // Along +y: right is +x, up is +z.
        View {
            eye: Point::new(0.0, 0.0, 0.0),
            target: Point::new(0.0, 20.0, 0.0),
            fov_deg: 90.0,
            width_px: 100,
            height_px: 100,
            near_mm: 0.5,
            far_mm: 1000.0,
        }
    }

    #[test]
    fn a_square_facing_the_camera_covers_its_projected_area_and_the_nearer_one_wins() {
        let p = Projector::new(&view()).unwrap();
        let mut img = Image::new(100, 100);
        // At y = 10 a 90 degree view spans 20 mm over 100 px: a square of
        // 4 mm side (x, z in [-2, 2]) covers 20 x 20 px.
        let q = |y: f64, s: f64| {
            [Point::new(-s, y, -s), Point::new(s, y, -s), Point::new(s, y, s), Point::new(-s, y, s)]
        };
        let far = q(10.0, 2.0);
        p.triangle(&mut img, &[far[0], far[1], far[2]], [0, 0, 255]);
        p.triangle(&mut img, &[far[0], far[2], far[3]], [0, 0, 255]);
        assert_eq!(img.coverage(), 400);
        assert_eq!(img.pixel(50, 50), Some([0, 0, 255]));
        // A nearer red square over part of it, drawn after: it wins.
        let near = q(5.0, 0.5);
        p.triangle(&mut img, &[near[0], near[1], near[2]], [255, 0, 0]);
        p.triangle(&mut img, &[near[0], near[2], near[3]], [255, 0, 0]);
        assert_eq!(img.pixel(50, 50), Some([255, 0, 0]));
        assert_eq!(img.coverage(), 400);
        // Drawn again behind the red one, blue loses.
        p.triangle(&mut img, &[far[0], far[1], far[2]], [0, 0, 255]);
        assert_eq!(img.pixel(50, 50), Some([255, 0, 0]));
        assert!(!img.drawn(10, 10));
    }

    #[test]
    fn a_triangle_through_the_near_plane_is_clipped_not_dropped() {
        let p = Projector::new(&view()).unwrap();
        let mut img = Image::new(100, 100);
        // From behind the eye to far ahead, on the floor z = -1.
        let floor = [Point::new(-3.0, -5.0, -1.0), Point::new(0.0, 50.0, -1.0), Point::new(3.0, -5.0, -1.0)];
        p.triangle(&mut img, &floor, [9, 9, 9]);
        assert!(img.coverage() > 0);
        assert!(img.drawn(50, 99), "the floor just below the centre, near the eye");
        assert!(!img.drawn(50, 40), "nothing above the horizon");
    }
}
