//! The continuous check: the time of first impact of parts moving from one pose
//! to another, so that a fast move cannot tunnel through a thin plate.
//!
//! A motion turns the part at a constant rate about a fixed axis through its
//! box centre while that centre travels a straight line (a screw-like motion that
//! ends exactly at the target pose). Impacts are found by conservative
//! advancement (Mirtich 1996) on the exact f64 distance: no point of a part can
//! travel faster than `|centre travel| + angle × radius`, so after measuring a
//! distance `d` nothing can touch before `d / speed`, and time advances by that
//! much until the distance is within the contact tolerance.

use dmu_geom::Aabb3d;
use dmu_scene::{PartId, Scene};
use dmu_tree::Tree;
use glam::{DAffine3, DMat3, DQuat, DVec3};

use crate::check::{Checker, ChunkPair, Impact, Report, Settings, run_end};
use crate::narrow::{PairSearch, Placement, pair_tolerance};

/// Conservative advancement gives up after this many steps for one pair of parts
/// (a part sliding past another a hair above the contact tolerance advances in
/// tiny steps) and reports the pair at the time reached: a possible impact,
/// never a missed one.
pub const MAX_ADVANCEMENT_STEPS: usize = 1000;

/// A part moving from one world pose to another. The poses must differ by a
/// rotation and a translation (the part's scale stays).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Motion {
    /// The part.
    pub part: PartId,
    /// World pose at the start (time 0).
    pub from: DAffine3,
    /// World pose at the end (time 1).
    pub to: DAffine3,
}

/// A motion prepared for interpolation.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Path {
    to: DAffine3,
    from: DAffine3,
    /// The part's box centre at the start and its travel, world.
    centre: DVec3,
    travel: DVec3,
    /// Rotation axis (unit) and total angle, radians in `[0, π]`.
    axis: DVec3,
    angle: f64,
}

/// The rotation taking pose `from`'s linear part to `to`'s (`to · from⁻¹`).
/// A part scaled to zero along some axis (glTF allows scale 0, e.g. to hide a
/// node) has no inverse: its frames are completed from the columns it has, so
/// the turn moves its (flat, thin or point-like) geometry exactly.
fn turn_between(from: &DMat3, to: &DMat3) -> DMat3 {
    let det = from.determinant();
    if det.is_normal() {
        return *to * from.inverse();
    }
    frame(to) * frame(from).transpose()
}

/// An orthonormal frame whose axes follow a linear map's non-zero columns, the
/// others completed by cross products (for a map of rotation times scale: the
/// rotation, wherever the scale is not zero).
fn frame(m: &DMat3) -> DMat3 {
    let cols = [m.x_axis, m.y_axis, m.z_axis].map(DVec3::try_normalize);
    let (x, y, z) = match cols {
        [Some(x), Some(y), _] => (x, y, x.cross(y)),
        [Some(x), None, Some(z)] => (x, z.cross(x), z),
        [None, Some(y), Some(z)] => (y.cross(z), y, z),
        [Some(x), None, None] => {
            let y = x.any_orthonormal_vector();
            (x, y, x.cross(y))
        }
        [None, Some(y), None] => {
            let z = y.any_orthonormal_vector();
            (y.cross(z), y, z)
        }
        [None, None, Some(z)] => {
            let x = z.any_orthonormal_vector();
            (x, z.cross(x), z)
        }
        [None, None, None] => (DVec3::X, DVec3::Y, DVec3::Z),
    };
    DMat3::from_cols(x, y, z)
}

/// When [`replay`](crate::replay) sweeps a step's motions.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SweepMode {
    /// Never: each step is checked at its end poses only (a fast move can
    /// pass through a thin part unseen).
    Off,
    /// Where a part moves more than its own thickness in one step, the only
    /// case where a discrete check can jump over a part as thick as itself;
    /// each such choice is reported as a [`SweepDecision`].
    #[default]
    Auto,
    /// Every motion of every step.
    Always,
}

/// Why a step's motions were swept: a part moved farther than it is thick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SweepDecision {
    /// The part that moved.
    pub part: PartId,
    /// How far its farthest point may have travelled: its box centre's travel
    /// plus the turn's arc at its radius, model units.
    pub moved: f64,
    /// Its thickness: the smallest side of its own box, scaled to the world,
    /// model units.
    pub thickness: f64,
}

impl SweepDecision {
    /// The decision for one motion, or `None` when the part moved no more than
    /// its thickness (a discrete check at the end pose suffices).
    pub fn of(scene: &Scene, motion: &Motion) -> Option<Self> {
        let local = scene.part_mesh(motion.part).bounds;
        if local.is_empty() {
            return None;
        }
        let path = Path::new(scene, motion);
        let moved = path.reach(path.radius(&local));
        let m = &motion.to.matrix3;
        let scale = DVec3::new(m.x_axis.length(), m.y_axis.length(), m.z_axis.length());
        let thickness = (local.extent().as_dvec3() * scale).min_element();
        (moved > thickness).then_some(Self {
            part: motion.part,
            moved,
            thickness,
        })
    }

    /// The decision in words, with the part's name: "part P moved 412 mm, more
    /// than its thickness 20 mm: continuous (swept) check".
    pub fn describe(&self, scene: &Scene) -> String {
        format!(
            "part {} moved {} model units, more than its thickness {}: continuous (swept) check",
            scene.part_name(self.part),
            round3(self.moved),
            round3(self.thickness)
        )
    }
}

/// A length shown to three decimals without trailing zeros.
fn round3(v: f64) -> String {
    let s = format!("{v:.3}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    s.to_owned()
}

impl Path {
    pub(crate) fn new(scene: &Scene, motion: &Motion) -> Self {
        let pivot = scene.part_mesh(motion.part).bounds.center().as_dvec3();
        let pivot = if pivot.is_finite() {
            pivot
        } else {
            DVec3::ZERO
        };
        let turn = turn_between(&motion.from.matrix3, &motion.to.matrix3);
        let residual = (turn.transpose() * turn - DMat3::IDENTITY).to_cols_array();
        assert!(
            residual.iter().all(|r| r.abs() < 1e-9),
            "motion of part {}: the poses differ by more than a rotation",
            motion.part
        );
        let q = DQuat::from_mat3(&turn).normalize();
        // The shorter way round; glam's to_axis_angle would drop angles under 2e-8.
        let q = if q.w < 0.0 { -q } else { q };
        let v = DVec3::new(q.x, q.y, q.z);
        let (axis, angle) = if v.length_squared() > 0.0 {
            (v.normalize(), 2.0 * v.length().atan2(q.w))
        } else {
            (DVec3::Z, 0.0)
        };
        let centre = motion.from.transform_point3(pivot);
        Self {
            from: motion.from,
            to: motion.to,
            centre,
            travel: motion.to.transform_point3(pivot) - centre,
            axis,
            angle,
        }
    }

    /// The pose at time `t` in `[0, 1]`.
    fn at(&self, t: f64) -> DAffine3 {
        DAffine3::from_translation(self.centre + self.travel * t)
            * DAffine3::from_axis_angle(self.axis, self.angle * t)
            * DAffine3::from_translation(-self.centre)
            * self.from
    }

    /// Radius of a local box about the centre at the start.
    fn radius(&self, local: &dmu_geom::Aabb3f) -> f64 {
        local
            .as_dvec()
            .corners()
            .iter()
            .map(|&c| self.from.transform_point3(c).distance(self.centre))
            .fold(0.0, f64::max)
    }

    /// Bound on how far any point within `radius` of the centre travels.
    fn reach(&self, radius: f64) -> f64 {
        self.travel.length() + self.angle * radius
    }

    /// A world box holding a local box at every time of the motion: the two end
    /// boxes' union, widened by how far the arc strays from the chord, cut down
    /// to the box swept by the ball about the centre.
    fn swept(&self, local: &dmu_geom::Aabb3f) -> Aabb3d {
        let radius = self.radius(local);
        let ends = local
            .transformed(&self.from)
            .union(local.transformed(&self.to))
            .inflated(radius * self.angle);
        let r = DVec3::splat(radius);
        let end = self.centre + self.travel;
        let ball =
            Aabb3d::new(self.centre - r, self.centre + r).union(Aabb3d::new(end - r, end + r));
        ends.intersection(ball)
    }
}

impl Checker {
    /// Time of first impact of the moving parts against every other visible part
    /// (static at its current pose in `scene`) and against each other, each
    /// moving along its [`Motion`]; found through the tree with each chunk's
    /// swept box. One [`Impact`] per part pair that meets, with the earliest
    /// time; a pair already touching or interpenetrating at the start meets at
    /// time 0. Hidden parts and allowed pairs are skipped. Static parts come from
    /// the tree; moving parts' tree entries are ignored, so the tree may hold
    /// them at either end.
    ///
    /// Exact up to the contact tolerance and f64 rounding, for translations and
    /// rotations alike; see [`MAX_ADVANCEMENT_STEPS`] for the one approximation.
    ///
    /// # Panics
    /// When a motion's poses differ by more than a rotation and a translation.
    pub fn sweep(
        &mut self,
        scene: &Scene,
        tree: &Tree,
        motions: &[Motion],
        settings: &Settings,
        report: &mut Report,
    ) {
        report.impacts.clear();
        self.paths.clear();
        self.paths
            .extend(motions.iter().map(|m| (m.part, Path::new(scene, m))));
        self.paths.sort_by_key(|(p, _)| *p);
        self.paths.dedup_by_key(|(p, _)| *p);
        self.moved.clear();
        self.moved.extend(self.paths.iter().map(|(p, _)| *p));
        let margin = self.margin(settings);
        self.swept.clear();
        for (part, path) in &self.paths {
            if scene.part(*part).hidden {
                continue;
            }
            for c in scene.part_mesh(*part).chunk_ids() {
                let b = path.swept(&scene.chunk(c).bounds).inflated(margin);
                self.swept.push((*part, c, b));
            }
        }
        self.pairs.clear();
        for i in 0..self.swept.len() {
            let (a, ca, query) = self.swept[i];
            self.found.clear();
            tree.entries_in_box(&query, &mut self.found);
            for &e in &self.found {
                let e = &tree.entries()[e.0 as usize];
                // Moving parts are met through their swept boxes, below.
                if self.moved.binary_search(&e.part).is_err()
                    && self.wanted(scene, settings, a, e.part)
                {
                    self.pairs.push(ChunkPair {
                        a,
                        b: e.part,
                        ca,
                        cb: e.chunk,
                    });
                }
            }
            for &(b, cb, other) in &self.swept {
                if b > a && self.wanted(scene, settings, a, b) && query.overlaps(&other) {
                    self.pairs.push(ChunkPair { a, b, ca, cb });
                }
            }
        }
        self.pairs.sort_unstable();
        let mut start = 0;
        while start < self.pairs.len() {
            let end = run_end(&self.pairs, start);
            report.part_pairs_tested += 1;
            if let Some(impact) = self.advance(scene, settings, start..end, report) {
                report.impacts.push(impact);
            }
            start = end;
        }
    }

    /// Conservative advancement of one pair of parts over their chunk pairs
    /// `self.pairs[run]`.
    fn advance(
        &self,
        scene: &Scene,
        settings: &Settings,
        run: std::ops::Range<usize>,
        report: &mut Report,
    ) -> Option<Impact> {
        let run = &self.pairs[run];
        let (a, b) = (run[0].a, run[0].b);
        let path_of = |p: PartId| {
            self.paths
                .binary_search_by_key(&p, |(q, _)| *q)
                .ok()
                .map(|i| &self.paths[i].1)
        };
        let path_a = path_of(a).expect("the first part of a swept pair moves");
        let path_b = path_of(b);
        let tolerance = pair_tolerance(scene, a, b, settings.contact_tolerance);
        let bounds = |p: PartId| scene.part_mesh(p).bounds;
        let speed = path_a.reach(path_a.radius(&bounds(a)))
            + path_b.map_or(0.0, |p| p.reach(p.radius(&bounds(b))));
        let static_b = scene.part_world(b);
        let mut t = 0.0;
        let mut last = None;
        for _ in 0..MAX_ADVANCEMENT_STEPS {
            let world_a = path_a.at(t);
            let world_b = path_b.map_or(static_b, |p| p.at(t));
            let origin = world_a.translation;
            let place_a = Placement::new(&world_a, origin);
            let place_b = Placement::new(&world_b, origin);
            // Only what is within reach for the rest of the motion matters.
            let mut search = PairSearch::new(tolerance, speed * (1.0 - t));
            self.search_chunk_pairs(scene, run, (&place_a, &place_b), &mut search, report);
            let best = search.best?;
            let impact = Impact {
                a,
                b,
                toi: t,
                distance: if best.penetrating { 0.0 } else { best.distance },
                point: origin + (best.point_a + best.point_b) * 0.5,
            };
            if best.penetrating || best.distance <= tolerance {
                return Some(impact);
            }
            last = Some(impact);
            t += best.distance / speed;
            if t > 1.0 {
                return None;
            }
        }
        // Out of steps: where advancement stopped (see MAX_ADVANCEMENT_STEPS).
        last
    }
}

#[cfg(test)]
mod tests {
    use glam::{DMat3, DQuat, DVec3};

    use super::turn_between;

    /// The turn between two poses of a part scaled to zero along some axes (it
    /// had no inverse, and the sweep panicked) is a rotation that takes every
    /// point of the first pose to the second, like the inverse does for
    /// regular poses.
    #[test]
    fn issue_20_turns_between_poses_with_zero_scales() {
        let (a, b) = (
            DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 0.7),
            DQuat::from_axis_angle(DVec3::new(-2.0, 0.5, 1.0).normalize(), 2.1),
        );
        for scale in [
            DVec3::new(2.0, 3.0, 0.5),
            DVec3::new(0.0, 3.0, 0.5),
            DVec3::new(2.0, 0.0, 0.5),
            DVec3::new(2.0, 3.0, 0.0),
            DVec3::new(0.0, 0.0, 0.5),
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(0.0, 3.0, 0.0),
            DVec3::ZERO,
            DVec3::new(-2.0, 0.0, 0.5),
        ] {
            let from = DMat3::from_quat(a) * DMat3::from_diagonal(scale);
            let to = DMat3::from_quat(b) * DMat3::from_diagonal(scale);
            let turn = turn_between(&from, &to);
            let residual = (turn.transpose() * turn - DMat3::IDENTITY).to_cols_array();
            assert!(residual.iter().all(|r| r.abs() < 1e-12), "{scale}: {turn}");
            for p in [DVec3::X, DVec3::Y, DVec3::Z, DVec3::new(0.3, -1.2, 2.5)] {
                let moved = turn * (from * p);
                assert!(moved.distance(to * p) < 1e-12, "{scale}, {p}");
            }
        }
    }
}
