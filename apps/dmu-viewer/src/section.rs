//! Section planes and the section box: what cuts the model open. A section
//! keeps the positive side of each of its planes (the side their normals
//! point to); the renderer cuts and caps with them and culls what they cut
//! away wholly, and picks see through what is cut away.

use anyhow::Context as _;
use dmu_geom::{Aabb3d, Plane, Short};
use dmu_render::MAX_SECTION_PLANES;
use dmu_scene::MAX_WORLD_COORDINATE;
use glam::DVec3;

/// What cuts the model open.
#[derive(Clone, Debug, Default, PartialEq)]
pub enum Section {
    /// Nothing: the whole model shows.
    #[default]
    Off,
    /// Up to [`MAX_SECTION_PLANES`] planes, each keeping its positive side.
    Planes(Vec<Plane>),
    /// A box: what lies outside it is cut away.
    Box(Aabb3d),
}

impl Section {
    /// The planes the renderer and the pick cut with (a box's six face
    /// planes, normals inward).
    pub fn planes(&self) -> Vec<Plane> {
        match self {
            Self::Off => Vec::new(),
            Self::Planes(p) => p.clone(),
            Self::Box(b) => box_planes(b).to_vec(),
        }
    }

    /// Whether `p` is kept (not cut away).
    pub fn keeps(&self, p: DVec3) -> bool {
        self.planes().iter().all(|pl| pl.signed_distance(p) >= 0.0)
    }

    /// Adds a plane (a box gives way to the plane alone). Refused beyond
    /// [`MAX_SECTION_PLANES`] planes, for a normal that is zero or not
    /// finite (any finite length is one: `[1e300, 0, 0]` faces `+X`), or a
    /// point outside the world (±[`MAX_WORLD_COORDINATE`]), which a BCF
    /// file could not hold.
    pub fn add_plane(&mut self, point: DVec3, normal: DVec3) -> anyhow::Result<()> {
        let plane = dmu_geom::is_within(point, MAX_WORLD_COORDINATE)
            .then(|| Plane::try_from_point_normal(point, normal))
            .flatten()
            .with_context(|| {
                format!(
                    "section plane through {} with normal {}: the point must be within ±{MAX_WORLD_COORDINATE:e} and the normal finite and not zero",
                    Short(point),
                    Short(normal)
                )
            })?;
        match self {
            Self::Planes(p) => {
                anyhow::ensure!(
                    p.len() < MAX_SECTION_PLANES,
                    "a section has at most {MAX_SECTION_PLANES} planes; remove one first"
                );
                p.push(plane);
            }
            _ => *self = Self::Planes(vec![plane]),
        }
        Ok(())
    }

    /// A section box; refused when it is empty, or not within the world
    /// (±[`MAX_WORLD_COORDINATE`]), which a BCF file could not hold.
    pub fn set_box(&mut self, min: DVec3, max: DVec3) -> anyhow::Result<()> {
        anyhow::ensure!(
            dmu_geom::is_within(min, MAX_WORLD_COORDINATE)
                && dmu_geom::is_within(max, MAX_WORLD_COORDINATE)
                && min.cmplt(max).all(),
            "section box {} .. {}: min must be below max on every axis, both within ±{MAX_WORLD_COORDINATE:e}",
            Short(min),
            Short(max)
        );
        *self = Self::Box(Aabb3d::new(min, max));
        Ok(())
    }

    /// The handles that slide the section, each a world point and the unit
    /// direction it slides along: a box's six face centres (outward), a
    /// plane's point nearest the centre of `bounds` (along its normal).
    pub fn handles(&self, bounds: &Aabb3d) -> Vec<(DVec3, DVec3)> {
        match self {
            Self::Off => Vec::new(),
            Self::Planes(p) => p
                .iter()
                .map(|pl| {
                    let c = bounds.center();
                    (c - pl.normal * pl.signed_distance(c), pl.normal)
                })
                .collect(),
            Self::Box(b) => box_planes(b)
                .iter()
                .map(|pl| {
                    let c = b.center();
                    (c - pl.normal * pl.signed_distance(c), -pl.normal)
                })
                .collect(),
        }
    }

    /// This section with handle `index` ([`Section::handles`]) slid by `by`
    /// along its direction (a box face stops at the opposite face, and
    /// anything at the world's edge, ±[`MAX_WORLD_COORDINATE`]).
    pub fn slid(&self, index: usize, by: f64) -> Self {
        let mut out = self.clone();
        // Kept within the world, as every section is (a BCF file holds it).
        let world = |x: f64| x.clamp(-MAX_WORLD_COORDINATE, MAX_WORLD_COORDINATE);
        match &mut out {
            Self::Off => {}
            Self::Planes(p) => {
                if let Some(pl) = p.get_mut(index) {
                    pl.d = world(pl.d - by);
                }
            }
            Self::Box(b) => {
                let axis = index / 2;
                if index.is_multiple_of(2) {
                    b.min[axis] = world(b.min[axis] - by).min(b.max[axis]);
                } else {
                    b.max[axis] = world(b.max[axis] + by).max(b.min[axis]);
                }
            }
        }
        out
    }

    /// For the report of an automated run: the kind, and the planes `(n, d)`
    /// or the box.
    pub fn json(&self) -> serde_json::Value {
        let facts = match self {
            Self::Off => SectionFacts::Off,
            Self::Planes(p) => SectionFacts::Planes {
                planes: p
                    .iter()
                    .map(|pl| PlaneFacts {
                        normal: pl.normal.to_array(),
                        d: pl.d,
                    })
                    .collect(),
            },
            Self::Box(b) => SectionFacts::Box {
                min: b.min.to_array(),
                max: b.max.to_array(),
            },
        };
        serde_json::to_value(facts).expect("plain data")
    }

    /// What of `bounds` a section box keeps (all of it for planes, or when
    /// the box misses it).
    pub fn kept_bounds(&self, bounds: Aabb3d) -> Aabb3d {
        match self {
            Self::Box(b) if b.overlaps(&bounds) => b.intersection(bounds),
            _ => bounds,
        }
    }

    /// A short description for the status line and the report.
    pub fn describe(&self) -> String {
        match self {
            Self::Off => "no section".to_owned(),
            Self::Planes(p) => format!("{} section plane(s)", p.len()),
            Self::Box(b) => format!("section box {} .. {}", Short(b.min), Short(b.max)),
        }
    }
}

/// The six face planes of a box, normals inward: -x, +x, -y, +y, -z, +z faces.
pub fn box_planes(b: &Aabb3d) -> [Plane; 6] {
    let face = |axis: DVec3, at: f64, inward: f64| Plane {
        normal: axis * inward,
        d: -inward * at,
    };
    [
        face(DVec3::X, b.min.x, 1.0),
        face(DVec3::X, b.max.x, -1.0),
        face(DVec3::Y, b.min.y, 1.0),
        face(DVec3::Y, b.max.y, -1.0),
        face(DVec3::Z, b.min.z, 1.0),
        face(DVec3::Z, b.max.z, -1.0),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Issue 48: a normal of `[1e300, 0, 0]` passed the old check (its
    /// squared length is infinite, so "greater than zero") and panicked in
    /// `Plane::from_point_normal`; boxes and planes beyond ±1e15 were kept and
    /// exported to BCF files the reader refuses.
    #[test]
    fn issue_48_sections_are_finite_and_in_the_world() {
        let mut s = Section::Off;
        s.add_plane(DVec3::new(0.0, 0.0, 2.0), DVec3::new(1e300, 0.0, 0.0))
            .unwrap();
        assert_eq!(s.planes()[0].normal, DVec3::X);
        s.add_plane(DVec3::ZERO, DVec3::new(0.0, 1e-320, 0.0))
            .unwrap();
        assert_eq!(s.planes()[1].normal, DVec3::Y);
        for (point, normal) in [
            (DVec3::ZERO, DVec3::ZERO),
            (DVec3::ZERO, DVec3::new(f64::INFINITY, 0.0, 0.0)),
            (DVec3::new(2e15, 0.0, 0.0), DVec3::X),
            (DVec3::new(f64::NAN, 0.0, 0.0), DVec3::X),
        ] {
            let err = s.add_plane(point, normal).unwrap_err().to_string();
            assert!(err.len() < 200, "a short message: {err}");
        }
        assert_eq!(s.planes().len(), 2, "refusals change nothing");
        let err = s
            .set_box(DVec3::splat(-1e300), DVec3::splat(1.0))
            .unwrap_err()
            .to_string();
        assert!(err.contains("-1e300") && err.len() < 200, "{err}");
        s.set_box(DVec3::splat(-1.0), DVec3::splat(1.0)).unwrap();
        for i in 0..6 {
            for by in [1e300, -1e300] {
                let b = s.slid(i, by).planes();
                assert!(b.iter().all(|p| p.d.abs() <= MAX_WORLD_COORDINATE), "{b:?}");
            }
        }
        let mut p = Section::Off;
        p.add_plane(DVec3::ZERO, DVec3::Z).unwrap();
        assert_eq!(p.slid(0, 1e300).planes()[0].d, -MAX_WORLD_COORDINATE);
    }

    /// A box keeps exactly the points inside it (faces included).
    #[test]
    fn a_box_keeps_what_is_inside() {
        let mut s = Section::Off;
        s.set_box(DVec3::new(-1.0, 0.0, 2.0), DVec3::new(1.0, 3.0, 5.0))
            .unwrap();
        for (p, kept) in [
            (DVec3::new(0.0, 1.0, 3.0), true),
            (DVec3::new(1.0, 3.0, 5.0), true),
            (DVec3::new(1.001, 1.0, 3.0), false),
            (DVec3::new(0.0, -0.5, 3.0), false),
            (DVec3::new(0.0, 1.0, 5.5), false),
        ] {
            assert_eq!(s.keeps(p), kept, "{p}");
        }
        assert!(s.set_box(DVec3::ONE, DVec3::ZERO).is_err());
    }

    /// Sliding a handle moves its face or plane along its direction: the
    /// handle lands where it was slid to.
    #[test]
    fn handles_slide_faces_and_planes() {
        let bounds = Aabb3d::new(DVec3::splat(-10.0), DVec3::splat(10.0));
        let mut s = Section::Off;
        s.set_box(DVec3::new(-1.0, -2.0, -3.0), DVec3::new(1.0, 2.0, 3.0))
            .unwrap();
        let before = s.handles(&bounds);
        assert_eq!(before.len(), 6);
        for (i, &(p, dir)) in before.iter().enumerate() {
            let after = s.slid(i, 0.5).handles(&bounds)[i];
            assert!(after.0.abs_diff_eq(p + dir * 0.5, 1e-12), "face {i}");
            // Sliding inward past the opposite face stops there.
            let squashed = s.slid(i, -100.0);
            let Section::Box(b) = squashed else { panic!() };
            assert_eq!(b.min[i / 2], b.max[i / 2]);
        }
        let mut s = Section::Off;
        s.add_plane(DVec3::new(0.0, 0.0, 4.0), -DVec3::Z).unwrap();
        let (p, dir) = s.handles(&bounds)[0];
        assert_eq!(p, DVec3::new(0.0, 0.0, 4.0));
        let slid = s.slid(0, 1.5);
        assert!(slid.handles(&bounds)[0].0.abs_diff_eq(p + dir * 1.5, 1e-12));
        assert!(!slid.keeps(DVec3::new(0.0, 0.0, 3.0)) && slid.keeps(DVec3::new(0.0, 0.0, 2.4)));
    }

    /// Planes keep their positive side, at most six, and slide along the normal.
    #[test]
    fn planes_keep_their_positive_side() {
        let mut s = Section::Off;
        s.add_plane(DVec3::new(0.0, 0.0, 10.0), -DVec3::Z).unwrap();
        assert!(s.keeps(DVec3::new(5.0, 5.0, 9.0)));
        assert!(!s.keeps(DVec3::new(5.0, 5.0, 11.0)));
        s = s.slid(0, 2.0);
        assert!(!s.keeps(DVec3::new(5.0, 5.0, 9.0)));
        assert!(s.keeps(DVec3::new(5.0, 5.0, 7.9)));
        for _ in 1..MAX_SECTION_PLANES {
            s.add_plane(DVec3::ZERO, DVec3::X).unwrap();
        }
        assert!(s.add_plane(DVec3::ZERO, DVec3::X).is_err());
        assert!(s.add_plane(DVec3::ZERO, DVec3::ZERO).is_err());
        assert!(s.add_plane(DVec3::NAN, DVec3::X).is_err());
    }
}

/// A section in a report, by kind.
#[derive(Debug, serde::Serialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
enum SectionFacts {
    Off,
    Planes { planes: Vec<PlaneFacts> },
    Box { min: [f64; 3], max: [f64; 3] },
}

/// A section plane in a report: its normal and offset.
#[derive(Debug, serde::Serialize)]
struct PlaneFacts {
    normal: [f64; 3],
    d: f64,
}
