//! A unit's plan: its areas and its parts (catalogue spec and unit-local f64
//! placement), before any of it reaches the scene. A plan is kept so that, past
//! the unique-geometry budget, whole units are replicated by instancing.

use glam::{DAffine3, DMat3, DVec3};

use super::catalog::{DNS, Mat, Spec, flange_pair_len};

/// The system a part belongs to: the third level of the assembly tree.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub(super) enum System {
    Struct,
    Equip,
    Pipe,
    Elec,
    Access,
    Clad,
}

impl System {
    /// The code used in node names.
    pub(super) fn code(self) -> &'static str {
        match self {
            Self::Struct => "STR",
            Self::Equip => "EQP",
            Self::Pipe => "PIPE",
            Self::Elec => "ELEC",
            Self::Access => "ACC",
            Self::Clad => "CLAD",
        }
    }
}

/// One planned part.
#[derive(Clone, Debug)]
pub(super) struct PlanPart {
    /// Index into [`UnitPlan::areas`].
    pub area: u16,
    pub system: System,
    pub spec: Spec,
    /// Placement relative to the unit's origin, millimetres.
    pub at: DAffine3,
}

/// A unit: areas (storeys or zones) and parts, relative to the unit's origin.
#[derive(Clone, Debug, Default)]
pub(super) struct UnitPlan {
    /// Where the unit's origin sits in its plot.
    pub anchor: DVec3,
    /// Area names and elevations.
    pub areas: Vec<(String, f64)>,
    /// Parts, emitted in this order (see [`UnitPlan::sort`]).
    pub parts: Vec<PlanPart>,
}

/// Shortest straight pipe worth placing.
const MIN_PIECE: f64 = 100.0;
/// Longest pipe spool between two joints.
pub(super) const MAX_SPOOL: f64 = 6000.0;

/// How a pipe run ends.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum End {
    /// At an equipment nozzle's flange face: one mating flange.
    Nozzle,
    /// A blind-flanged end (a flange pair).
    Blind,
}

/// A pipe run through corner points (integer millimetres, each leg along an
/// axis, consecutive legs perpendicular).
#[derive(Clone, Debug)]
pub(super) struct Route {
    pub dn: u8,
    pub mat: Mat,
    pub points: Vec<DVec3>,
    pub start: End,
    pub end: End,
    /// The leg that gets a gate valve in its middle, if it is long enough.
    pub valve_leg: Option<usize>,
}

/// A rotation whose X axis is `x` (unit), Z as close to `z_hint` as possible.
pub(super) fn basis(x: DVec3, z_hint: DVec3) -> DMat3 {
    let hint = if x.dot(z_hint).abs() < 0.9 {
        z_hint
    } else if x.x.abs() < 0.9 {
        DVec3::X
    } else {
        DVec3::Y
    };
    let y = hint.cross(x).normalize();
    DMat3::from_cols(x, y, x.cross(y))
}

/// A placement by rotation and position.
pub(super) fn place(rotation: DMat3, at: DVec3) -> DAffine3 {
    DAffine3::from_mat3_translation(rotation, at)
}

/// A translation.
pub(super) fn at(x: f64, y: f64, z: f64) -> DAffine3 {
    DAffine3::from_translation(DVec3::new(x, y, z))
}

/// Turns local X to world Z (local Y to world X): columns, vertical rounds.
pub(super) const UPRIGHT: DMat3 = DMat3::from_cols(DVec3::Z, DVec3::X, DVec3::Y);
/// Turns local X to world Y: beams along Y.
pub(super) const ALONG_Y: DMat3 = DMat3::from_cols(DVec3::Y, DVec3::NEG_X, DVec3::Z);

impl UnitPlan {
    /// A plan whose origin sits at `anchor` in its plot.
    pub(super) fn new(anchor: DVec3) -> Self {
        Self {
            anchor,
            ..Self::default()
        }
    }

    /// Adds an area at elevation `z`.
    pub(super) fn area(&mut self, name: impl Into<String>, z: f64) -> u16 {
        self.areas.push((name.into(), z));
        u16::try_from(self.areas.len() - 1).expect("too many areas")
    }

    /// Adds a part.
    pub(super) fn put(&mut self, area: u16, system: System, spec: Spec, at: DAffine3) {
        self.parts.push(PlanPart {
            area,
            system,
            spec,
            at,
        });
    }

    /// Orders the parts by area, then system, keeping their order inside each:
    /// a unit cut short by the triangle budget loses its top storeys.
    pub(super) fn sort(&mut self) {
        self.parts.sort_by_key(|p| (p.area, p.system));
    }

    /// Plans a pipe run: straight spools (joined by flange pairs past
    /// [`MAX_SPOOL`]), elbows at the corners, end flanges and maybe a valve,
    /// its stem level (clear of the pipes in the lanes above). Returns the
    /// valve's centre if it got one; plans nothing and returns `None` when a leg
    /// is too short for its fittings.
    pub(super) fn pipe(&mut self, area: u16, route: &Route) -> Option<Option<DVec3>> {
        let points = simplify(&route.points);
        if points.len() < 2 {
            return None;
        }
        let mut valve = None;
        let p = DNS[route.dn as usize];
        let (bend, fl, fp) = (
            f64::from(p.bend),
            f64::from(p.flange_len),
            f64::from(flange_pair_len(route.dn)),
        );
        let end_len = |end: End| match end {
            End::Nozzle => fl,
            End::Blind => fp,
        };
        let legs = points.len() - 1;
        let mut plan = Vec::new();
        let mut put = |spec: Spec, at: DAffine3| {
            plan.push(PlanPart {
                area,
                system: System::Pipe,
                spec,
                at,
            })
        };
        let (dn, mat) = (route.dn, route.mat);
        for leg in 0..legs {
            let (a, b) = (points[leg], points[leg + 1]);
            let len = (b - a).length();
            let dir = (b - a) / len;
            if leg > 0 {
                let before = (a - points[leg - 1]).normalize();
                if before.dot(dir).abs() > 1e-9 {
                    return None;
                }
                put(
                    Spec::Elbow { dn, mat },
                    place(DMat3::from_cols(before, dir, before.cross(dir)), a),
                );
            }
            let s0 = if leg == 0 { end_len(route.start) } else { bend };
            let s1 = if leg + 1 == legs {
                end_len(route.end)
            } else {
                bend
            };
            let avail = len - s0 - s1;
            if avail < MIN_PIECE {
                return None;
            }
            let from = a + dir * s0;
            let valve_len = f64::from(p.valve_len);
            let left = ((avail - valve_len) * 0.5 / 50.0).floor() * 50.0;
            if route.valve_leg == Some(leg) && left >= MIN_PIECE + 200.0 {
                straight(&mut put, dn, mat, from, dir, left, fp);
                let valve_at = from + dir * (left + valve_len * 0.5);
                let stem = if dir.x.abs() > 0.5 {
                    DVec3::Y
                } else {
                    DVec3::X
                };
                put(Spec::Valve { dn }, place(basis(dir, stem), valve_at));
                valve = Some(valve_at);
                straight(
                    &mut put,
                    dn,
                    mat,
                    from + dir * (left + valve_len),
                    dir,
                    avail - left - valve_len,
                    fp,
                );
            } else {
                straight(&mut put, dn, mat, from, dir, avail, fp);
            }
        }
        let first_dir = (points[1] - points[0]).normalize();
        let last_dir = (points[legs] - points[legs - 1]).normalize();
        let (first, last) = (points[0], points[legs]);
        match route.start {
            End::Nozzle => put(
                Spec::Flange { dn, mat },
                place(basis(-first_dir, DVec3::Z), first + first_dir * fl * 0.5),
            ),
            End::Blind => put(
                Spec::FlangePair { dn, mat },
                place(basis(first_dir, DVec3::Z), first + first_dir * fp * 0.5),
            ),
        }
        match route.end {
            End::Nozzle => put(
                Spec::Flange { dn, mat },
                place(basis(last_dir, DVec3::Z), last - last_dir * fl * 0.5),
            ),
            End::Blind => put(
                Spec::FlangePair { dn, mat },
                place(basis(last_dir, DVec3::Z), last - last_dir * fp * 0.5),
            ),
        }
        self.parts.append(&mut plan);
        Some(valve)
    }
}

/// Straight pipe from `from` along `dir` for `len`: spools of at most
/// [`MAX_SPOOL`] joined by flange pairs `fp` long.
fn straight(
    put: &mut impl FnMut(Spec, DAffine3),
    dn: u8,
    mat: Mat,
    from: DVec3,
    dir: DVec3,
    len: f64,
    fp: f64,
) {
    let rotation = basis(dir, DVec3::Z);
    let mut pos = from;
    let mut left = len;
    while left > MAX_SPOOL + fp + MIN_PIECE * 2.0 {
        put(
            Spec::Pipe {
                dn,
                len: MAX_SPOOL as u32,
                mat,
            },
            place(rotation, pos + dir * MAX_SPOOL * 0.5),
        );
        put(
            Spec::FlangePair { dn, mat },
            place(rotation, pos + dir * (MAX_SPOOL + fp * 0.5)),
        );
        pos += dir * (MAX_SPOOL + fp);
        left -= MAX_SPOOL + fp;
    }
    put(
        Spec::Pipe {
            dn,
            len: left.round() as u32,
            mat,
        },
        place(rotation, pos + dir * left * 0.5),
    );
}

/// Drops repeated points and the middle of three collinear ones.
fn simplify(points: &[DVec3]) -> Vec<DVec3> {
    let mut out: Vec<DVec3> = Vec::with_capacity(points.len());
    for &p in points {
        if out.last().is_some_and(|&q| q.distance(p) < 0.5) {
            continue;
        }
        if out.len() >= 2 {
            let (a, b) = (out[out.len() - 2], out[out.len() - 1]);
            if (b - a).normalize().dot((p - b).normalize()) > 1.0 - 1e-9 {
                out.pop();
            }
        }
        out.push(p);
    }
    out
}
