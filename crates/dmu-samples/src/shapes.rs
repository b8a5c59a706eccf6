//! Tessellated solids for the procedural samples: boxes, extruded profiles,
//! cylinders and cones, torus segments and dished heads, written into one
//! [`MeshData`] in the part's local frame.
//!
//! Every solid is emitted through a rigid placement ([`Tess::xf`]) with the current
//! material ([`Tess::material`]), so a composite part (a valve, a pump) is a few
//! calls. Conventions: counter-clockwise triangles seen from outside, unit outward
//! normals (flat on planar faces, smooth on curved ones), and no zero-area triangle:
//! cones end in one triangle per segment instead of a collapsed quad.

use std::f32::consts::TAU;

use glam::{Affine3A, Mat3, Vec2, Vec3};

use dmu_scene::MaterialId;
use dmu_scene::MeshData;

/// Writes solids into a mesh; holds the current placement and material.
#[derive(Debug)]
pub(crate) struct Tess {
    mesh: MeshData,
    pos: Vec<Vec3>,
    nrm: Vec<Vec3>,
    idx: Vec<u32>,
    /// Rigid placement applied to the next solids (rotation and translation only,
    /// so normals transform with its linear part).
    pub xf: Affine3A,
    /// Material of the next solids.
    pub material: MaterialId,
}

/// Cap triangles of a rectangle outline (four corners, counter-clockwise).
pub(crate) const RECT_CAP: [[u32; 3]; 2] = [[0, 1, 2], [0, 2, 3]];

impl Tess {
    /// An empty mesh named `name`, placed at the identity, with `material`.
    pub(crate) fn new(name: impl Into<String>, material: MaterialId) -> Self {
        Self {
            mesh: MeshData {
                name: name.into(),
                ..MeshData::default()
            },
            pos: Vec::new(),
            nrm: Vec::new(),
            idx: Vec::new(),
            xf: Affine3A::IDENTITY,
            material,
        }
    }

    /// The finished mesh.
    pub(crate) fn finish(self) -> MeshData {
        self.mesh
    }

    /// Moves the scratch solid through the placement into the mesh.
    fn emit(&mut self) {
        let xf = self.xf;
        for p in &mut self.pos {
            *p = xf.transform_point3(*p);
        }
        for n in &mut self.nrm {
            *n = xf.transform_vector3(*n).normalize_or(Vec3::Z);
        }
        self.mesh
            .push_primitive(&self.pos, &self.nrm, &self.idx, self.material);
        self.pos.clear();
        self.nrm.clear();
        self.idx.clear();
    }

    fn vertex(&mut self, p: Vec3, n: Vec3) -> u32 {
        self.pos.push(p);
        self.nrm.push(n);
        (self.pos.len() - 1) as u32
    }

    fn tri(&mut self, a: u32, b: u32, c: u32) {
        self.idx.extend_from_slice(&[a, b, c]);
    }

    /// A prism along local X from `x0` to `x1 > x0` whose cross-section is
    /// `outline` in the (y, z) plane, counter-clockwise seen from +X; `cap` are
    /// triangles of the outline (indices into it, counter-clockwise too).
    /// Sides and caps are flat shaded.
    pub(crate) fn extrude(&mut self, outline: &[Vec2], cap: &[[u32; 3]], x0: f32, x1: f32) {
        debug_assert!(x1 > x0 && outline.len() >= 3);
        let n = outline.len();
        for k in 0..n {
            let (p, q) = (outline[k], outline[(k + 1) % n]);
            let e = q - p;
            // Outward normal of a counter-clockwise edge: the edge turned clockwise.
            let normal = Vec3::new(0.0, e.y, -e.x).normalize();
            let a = self.vertex(Vec3::new(x0, p.x, p.y), normal);
            let b = self.vertex(Vec3::new(x0, q.x, q.y), normal);
            let c = self.vertex(Vec3::new(x1, q.x, q.y), normal);
            let d = self.vertex(Vec3::new(x1, p.x, p.y), normal);
            self.tri(a, b, c);
            self.tri(a, c, d);
        }
        for (x, normal) in [(x0, -Vec3::X), (x1, Vec3::X)] {
            let base = self.pos.len() as u32;
            for p in outline {
                self.vertex(Vec3::new(x, p.x, p.y), normal);
            }
            for t in cap {
                if normal.x > 0.0 {
                    self.tri(base + t[0], base + t[1], base + t[2]);
                } else {
                    self.tri(base + t[0], base + t[2], base + t[1]);
                }
            }
        }
        self.emit();
    }

    /// An axis-aligned box (in the placement's frame) from `min` to `max`.
    pub(crate) fn cuboid(&mut self, min: Vec3, max: Vec3) {
        let outline = [
            Vec2::new(min.y, min.z),
            Vec2::new(max.y, min.z),
            Vec2::new(max.y, max.z),
            Vec2::new(min.y, max.z),
        ];
        self.extrude(&outline, &RECT_CAP, min.x, max.x);
    }

    /// A box of size `size` centred on `centre`.
    pub(crate) fn block(&mut self, centre: Vec3, size: Vec3) {
        self.cuboid(centre - size * 0.5, centre + size * 0.5);
    }

    /// A round solid along local X from `x0` to `x1 > x0`, radius `r0` at `x0` and
    /// `r1` at `x1` (one of them may be zero: a cone), with `seg` segments around
    /// and flat end caps where `caps` says so (a zero radius needs none).
    pub(crate) fn frustum(
        &mut self,
        x0: f32,
        x1: f32,
        r0: f32,
        r1: f32,
        seg: u32,
        caps: (bool, bool),
    ) {
        debug_assert!(x1 > x0 && seg >= 3 && (r0 > 0.0 || r1 > 0.0));
        let slope = (r0 - r1) / (x1 - x0);
        let ring = |i: u32| {
            let a = TAU * i as f32 / seg as f32;
            Vec2::new(a.cos(), a.sin())
        };
        let side = |c: Vec2| Vec3::new(slope, c.x, c.y).normalize();
        let base = self.pos.len() as u32;
        if r0 > 0.0 && r1 > 0.0 {
            for i in 0..seg {
                let c = ring(i);
                self.vertex(Vec3::new(x0, r0 * c.x, r0 * c.y), side(c));
                self.vertex(Vec3::new(x1, r1 * c.x, r1 * c.y), side(c));
            }
            for i in 0..seg {
                let j = (i + 1) % seg;
                let (a0, b0, a1, b1) = (
                    base + 2 * i,
                    base + 2 * i + 1,
                    base + 2 * j,
                    base + 2 * j + 1,
                );
                self.tri(a0, a1, b1);
                self.tri(a0, b1, b0);
            }
        } else {
            // A cone: the apex gets one vertex per segment, normal at mid-angle.
            let (x_ring, r, x_apex) = if r0 > 0.0 { (x0, r0, x1) } else { (x1, r1, x0) };
            for i in 0..seg {
                let c = ring(i);
                self.vertex(Vec3::new(x_ring, r * c.x, r * c.y), side(c));
            }
            for i in 0..seg {
                let mid = TAU * (i as f32 + 0.5) / seg as f32;
                let apex = self.vertex(
                    Vec3::new(x_apex, 0.0, 0.0),
                    side(Vec2::new(mid.cos(), mid.sin())),
                );
                let (a, b) = (base + i, base + (i + 1) % seg);
                if r0 > 0.0 {
                    self.tri(a, b, apex);
                } else {
                    self.tri(apex, b, a);
                }
            }
        }
        for (x, r, normal, wanted) in [(x0, r0, -Vec3::X, caps.0), (x1, r1, Vec3::X, caps.1)] {
            if !wanted || r <= 0.0 {
                continue;
            }
            let centre = self.vertex(Vec3::new(x, 0.0, 0.0), normal);
            let first = self.pos.len() as u32;
            for i in 0..seg {
                let c = ring(i);
                self.vertex(Vec3::new(x, r * c.x, r * c.y), normal);
            }
            for i in 0..seg {
                let (a, b) = (first + i, first + (i + 1) % seg);
                if normal.x > 0.0 {
                    self.tri(centre, a, b);
                } else {
                    self.tri(centre, b, a);
                }
            }
        }
        self.emit();
    }

    /// A closed cylinder along local X from `x0` to `x1`.
    pub(crate) fn cylinder(&mut self, x0: f32, x1: f32, r: f32, seg: u32) {
        self.frustum(x0, x1, r, r, seg, (true, true));
    }

    /// A tube bent around the local Z axis: its centre line is the arc of radius
    /// `bend` from angle 0 (point (bend, 0, 0), heading +Y) to `angle`, with
    /// `steps` steps along the arc and `seg` segments around; `caps` closes both
    /// ends (leave them open for a full ring).
    pub(crate) fn torus(
        &mut self,
        bend: f32,
        tube: f32,
        angle: f32,
        steps: u32,
        seg: u32,
        caps: bool,
    ) {
        debug_assert!(bend > tube && steps >= 1 && seg >= 3);
        let full = (angle - TAU).abs() < 1e-4;
        let rings = if full { steps } else { steps + 1 };
        let base = self.pos.len() as u32;
        for s in 0..rings {
            let theta = angle * s as f32 / steps as f32;
            let radial = Vec3::new(theta.cos(), theta.sin(), 0.0);
            for i in 0..seg {
                let phi = TAU * i as f32 / seg as f32;
                let n = radial * phi.cos() + Vec3::Z * phi.sin();
                self.vertex(radial * bend + n * tube, n);
            }
        }
        for s in 0..steps {
            let (ra, rb) = (s, (s + 1) % rings);
            for i in 0..seg {
                let j = (i + 1) % seg;
                let (a0, a1) = (base + ra * seg + i, base + ra * seg + j);
                let (b0, b1) = (base + rb * seg + i, base + rb * seg + j);
                self.tri(a0, b0, b1);
                self.tri(a0, b1, a1);
            }
        }
        if caps && !full {
            for (theta, start) in [(0.0f32, true), (angle, false)] {
                let radial = Vec3::new(theta.cos(), theta.sin(), 0.0);
                let heading = Vec3::new(-theta.sin(), theta.cos(), 0.0);
                let normal = if start { -heading } else { heading };
                let centre = self.vertex(radial * bend, normal);
                let first = self.pos.len() as u32;
                for i in 0..seg {
                    let phi = TAU * i as f32 / seg as f32;
                    self.vertex(
                        radial * bend + (radial * phi.cos() + Vec3::Z * phi.sin()) * tube,
                        normal,
                    );
                }
                for i in 0..seg {
                    let (a, b) = (first + i, first + (i + 1) % seg);
                    if start {
                        self.tri(centre, a, b);
                    } else {
                        self.tri(centre, b, a);
                    }
                }
            }
        }
        self.emit();
    }

    /// Half an ellipsoid bulging towards +X: a base ring of radius `radius` at
    /// x = 0 and the apex at x = `depth` (a 2:1 elliptical vessel head has
    /// `depth = radius / 2`), with `rings` rings and `seg` segments around. Open at
    /// the base, where it meets a shell.
    pub(crate) fn dish(&mut self, radius: f32, depth: f32, rings: u32, seg: u32) {
        debug_assert!(radius > 0.0 && depth > 0.0 && rings >= 1 && seg >= 3);
        let normal_at = |p: Vec3| {
            Vec3::new(
                p.x / (depth * depth),
                p.y / (radius * radius),
                p.z / (radius * radius),
            )
        };
        let base = self.pos.len() as u32;
        for k in 0..rings {
            let alpha = std::f32::consts::FRAC_PI_2 * k as f32 / rings as f32;
            for i in 0..seg {
                let phi = TAU * i as f32 / seg as f32;
                let p = Vec3::new(
                    depth * alpha.sin(),
                    radius * alpha.cos() * phi.cos(),
                    radius * alpha.cos() * phi.sin(),
                );
                self.vertex(p, normal_at(p).normalize());
            }
        }
        for k in 0..rings - 1 {
            for i in 0..seg {
                let j = (i + 1) % seg;
                let (a0, a1) = (base + k * seg + i, base + k * seg + j);
                let (b0, b1) = (a0 + seg, a1 + seg);
                self.tri(a0, a1, b1);
                self.tri(a0, b1, b0);
            }
        }
        let apex = self.vertex(Vec3::new(depth, 0.0, 0.0), Vec3::X);
        let last = base + (rings - 1) * seg;
        for i in 0..seg {
            self.tri(last + i, last + (i + 1) % seg, apex);
        }
        self.emit();
    }
}

/// The rigid placement whose local X is `x` and local Y is `y` (both unit and
/// perpendicular), with its origin at `origin`.
pub(crate) fn frame(origin: Vec3, x: Vec3, y: Vec3) -> Affine3A {
    Affine3A::from_mat3_translation(Mat3::from_cols(x, y, x.cross(y)), origin)
}

/// A placement at `origin` whose local X is the unit vector `x`, with the other
/// axes chosen deterministically (local Z as close to +Z as possible).
pub(crate) fn along(origin: Vec3, x: Vec3) -> Affine3A {
    let helper = if x.z.abs() > 0.9 { Vec3::Y } else { Vec3::Z };
    let y = helper.cross(x).normalize();
    frame(origin, x, y)
}

/// The outline of an I (or H) section, `h` deep along local z, `b` wide along
/// local y, web `tw` and flanges `tf` thick, centred, with its cap triangles.
pub(crate) fn i_section(h: f32, b: f32, tw: f32, tf: f32) -> ([Vec2; 12], [[u32; 3]; 10]) {
    let (h2, b2, w2) = (h * 0.5, b * 0.5, tw * 0.5);
    let outline = [
        Vec2::new(-b2, -h2),
        Vec2::new(b2, -h2),
        Vec2::new(b2, -h2 + tf),
        Vec2::new(w2, -h2 + tf),
        Vec2::new(w2, h2 - tf),
        Vec2::new(b2, h2 - tf),
        Vec2::new(b2, h2),
        Vec2::new(-b2, h2),
        Vec2::new(-b2, h2 - tf),
        Vec2::new(-w2, h2 - tf),
        Vec2::new(-w2, -h2 + tf),
        Vec2::new(-b2, -h2 + tf),
    ];
    // Bottom flange fanned from its corner 0, the web, the top flange from corner 6:
    // every triangle has positive area (no three collinear corners).
    let cap = [
        [0, 1, 2],
        [0, 2, 3],
        [0, 3, 10],
        [0, 10, 11],
        [10, 3, 4],
        [10, 4, 9],
        [6, 7, 8],
        [6, 8, 9],
        [6, 9, 4],
        [6, 4, 5],
    ];
    (outline, cap)
}

/// The outline of a channel (C) section, `h` deep along local z, flanges `b` long
/// towards +y, all walls `t` thick, with its web on y = 0, and its cap triangles.
pub(crate) fn c_section(h: f32, b: f32, t: f32) -> ([Vec2; 8], [[u32; 3]; 6]) {
    let outline = [
        Vec2::new(0.0, 0.0),
        Vec2::new(b, 0.0),
        Vec2::new(b, t),
        Vec2::new(t, t),
        Vec2::new(t, h - t),
        Vec2::new(b, h - t),
        Vec2::new(b, h),
        Vec2::new(0.0, h),
    ];
    let cap = [
        [0, 1, 2],
        [0, 2, 3],
        [0, 3, 4],
        [0, 4, 7],
        [7, 4, 5],
        [7, 5, 6],
    ];
    (outline, cap)
}
