//! A process building: a steel frame of bays and storeys with concrete or grated
//! floors, equipment on each floor, pipes under each ceiling, cable trays,
//! lights, an outside caged ladder with landings, and on most buildings wall
//! cladding and a parapet; the rest get handrails and more bracing.
//!
//! Layout inside a storey, so that systems do not clash: equipment stands in bay
//! centres below the pipe lanes; pipes run in lanes (one elevation each) under
//! the beams, rising from equipment nozzles, and leave through the front wall
//! (y = 0) towards the pipe rack; headers run along X near a grid line; the cable
//! tray runs along the back wall; lights sit off-centre under the slab.

use glam::{DMat3, DVec3};

use super::Scale;
use super::catalog::{
    DNS, Mat, SEC_BEAM, SEC_COLUMN, SEC_JOIST, SERVICES, Spec, drum_nozzle, pump_dn, pump_extent,
    pump_top, vessel_top,
};
use super::unit::{ALONG_Y, End, Route, System, UPRIGHT, UnitPlan, at, basis, place};
use crate::Rng;

/// Distance from the plot's front (rack side) to the building's front wall.
const FRONT: f64 = 14_000.0;
/// Vertical pitch of the pipe lanes.
const LANE_PITCH: f64 = 350.0;

/// A pipe connection on a piece of equipment: flange face, pointing up.
#[derive(Clone, Copy, Debug)]
struct Nozzle {
    at: DVec3,
    dn: u8,
}

fn pick<T: Copy>(rng: &mut Rng, items: &[T]) -> T {
    items[rng.below(items.len() as u64) as usize]
}

/// Plans a building centred in a plot `plot_x` wide.
pub(super) fn building(rng: &mut Rng, scale: Scale, plot_x: f64) -> UnitPlan {
    let bx: f64 = if scale != Scale::Tiny && rng.chance(0.35) {
        7500.0
    } else {
        6000.0
    };
    let by: f64 = 6000.0;
    let (nx, ny, storeys) = match scale {
        Scale::Tiny => (2, 1, 1),
        Scale::Small => (2 + rng.below(2) as usize, 2, 2 + rng.below(2) as usize),
        Scale::Full => {
            let nx = if bx > 6000.0 {
                3 + rng.below(2)
            } else {
                3 + rng.below(4)
            };
            (
                nx as usize,
                2 + rng.below(3) as usize,
                3 + rng.below(3) as usize,
            )
        }
    };
    let (w, d) = (nx as f64 * bx, ny as f64 * by);
    let clad = rng.chance(0.65);
    let clad_mat = if rng.chance(0.5) {
        Mat::Cladding
    } else {
        Mat::CladdingAlt
    };
    let mut z = vec![0.0];
    for s in 0..storeys {
        let h = if s == 0 {
            pick(rng, &[6500.0, 7000.0, 7500.0])
        } else {
            pick(rng, &[5500.0, 6000.0, 6500.0])
        };
        z.push(z[s] + h);
    }
    let concrete: Vec<bool> = (0..=storeys)
        .map(|l| l == 0 || l == storeys || rng.chance(0.6))
        .collect();
    let thick = |l: usize| if concrete[l] { 250.0 } else { 40.0 };
    let xs = |i: usize| i as f64 * bx;
    let ys = |j: usize| j as f64 * by;

    let mut plan = UnitPlan::new(DVec3::new(
        ((plot_x - w) * 0.5 / 500.0).round() * 500.0,
        FRONT,
        0.0,
    ));
    let areas: Vec<u16> = (0..storeys)
        .map(|s| plan.area(format!("L{s}"), z[s]))
        .collect();
    let roof = plan.area("RF", z[storeys]);
    let level_area = |l: usize| if l < storeys { areas[l] } else { roof };
    let door = rng.below(nx as u64) as usize;

    // Floors: the ground slab, then one panel per bay and level.
    plan.put(
        areas[0],
        System::Struct,
        Spec::Block {
            size: [w as u32 + 2000, d as u32 + 2000, 400],
            mat: Mat::Concrete,
        },
        at(w * 0.5, d * 0.5, -200.0),
    );
    for l in 1..=storeys {
        let t = thick(l);
        let mat = if concrete[l] {
            Mat::Concrete
        } else {
            Mat::Grating
        };
        for j in 0..ny {
            for i in 0..nx {
                let size = [bx as u32, by as u32, t as u32];
                plan.put(
                    level_area(l),
                    System::Struct,
                    Spec::Block { size, mat },
                    at(xs(i) + bx * 0.5, ys(j) + by * 0.5, z[l] - t * 0.5),
                );
            }
        }
    }

    for s in 0..storeys {
        let area = areas[s];
        let bottom = if s == 0 { 30.0 } else { z[s] };
        let top = z[s + 1] - thick(s + 1);
        frame(&mut plan, area, s, [nx, ny], [bx, by], [bottom, top]);
        let zc = top - 550.0;
        let lanes = (((zc - z[s] - 2800.0) / LANE_PITCH).floor() as usize).clamp(3, 5);
        let lane_z = |k: usize| zc - 200.0 - LANE_PITCH * k as f64;
        let eq_top = lane_z(lanes - 1) - 650.0 - z[s];
        let storey = Storey {
            area,
            s,
            scale,
            n: [nx, ny],
            bay: [bx, by],
            floor: z[s],
            max_h: eq_top,
        };
        let nozzles = equipment(&mut plan, rng, &storey);

        // Headers along X, hung from the joists.
        let headers = (1 + rng.below(2) as usize).min(ny).min(lanes - 2);
        let mut rows: Vec<usize> = (0..ny).collect();
        for k in 0..headers {
            let j = rows.swap_remove(rng.below(rows.len() as u64) as usize);
            let (y, zh) = (ys(j) + 800.0, lane_z(k));
            let dn = 3 + rng.below(2) as u8;
            let route = Route {
                dn,
                mat: pick(rng, &SERVICES),
                points: vec![DVec3::new(600.0, y, zh), DVec3::new(w - 600.0, y, zh)],
                start: End::Blind,
                end: End::Blind,
                valve_leg: rng.chance(0.6).then_some(0),
            };
            if let Some(valve) = plan.pipe(area, &route) {
                let r = f64::from(DNS[dn as usize].od) * 0.5;
                let drop = ((top - 300.0) - (zh + r + 14.0)).round() as u32;
                for i in 0..nx {
                    let x = xs(i) + bx * 0.5;
                    if valve.is_none_or(|v| (v.x - x).abs() > 600.0) {
                        plan.put(area, System::Pipe, Spec::Hanger { dn, drop }, at(x, y, zh));
                    }
                }
            }
        }
        let exits = routes(&mut plan, rng, area, &nozzles, bx, headers..lanes, lane_z);

        // Cable tray along the back wall, lights, junction boxes.
        let tw = pick(rng, &[300u32, 450, 600]);
        let (yt, zt) = (d - 700.0, zc - 200.0);
        let drop = ((top - 300.0) - zt).round() as u32;
        for i in 0..nx {
            let x = xs(i) + bx * 0.5;
            plan.put(
                area,
                System::Elec,
                Spec::Tray {
                    len: bx as u32 - 40,
                    w: tw,
                },
                at(x, yt, zt),
            );
            plan.put(
                area,
                System::Elec,
                Spec::TraySupport { w: tw, drop },
                at(x, yt, zt),
            );
        }
        for j in 0..ny {
            for i in 0..nx {
                plan.put(
                    area,
                    System::Elec,
                    Spec::Light,
                    at(xs(i) + bx * 0.3, ys(j) + by * 0.3, top),
                );
            }
        }
        for i in 1..nx {
            if rng.chance(0.35) {
                let size = [400, 200, 500];
                plan.put(
                    area,
                    System::Elec,
                    Spec::Block {
                        size,
                        mat: Mat::Cabinet,
                    },
                    at(xs(i), d - 250.0, z[s] + 1500.0),
                );
            }
        }

        // The outside ladder up to the next landing, which has two handrails.
        let y_ladder = by * 0.5 + if s % 2 == 0 { -500.0 } else { 500.0 };
        plan.put(
            area,
            System::Access,
            Spec::Ladder {
                h: (z[s + 1] - z[s]) as u32,
            },
            at(w + 1480.0, y_ladder, z[s]),
        );
        let landing = level_area(s + 1);
        let zl = z[s + 1];
        plan.put(
            landing,
            System::Access,
            Spec::Block {
                size: [1100, 2400, 40],
                mat: Mat::Grating,
            },
            at(w + 850.0, by * 0.5, zl - 20.0),
        );
        for side in [-1.0, 1.0] {
            plan.put(
                landing,
                System::Access,
                Spec::Handrail { len: 1000 },
                at(w + 850.0, by * 0.5 + side * 1150.0, zl),
            );
        }

        if clad {
            // Ground panels start above the column base plates.
            let z0 = z[s] + if s == 0 { 40.0 } else { 10.0 };
            let h = z[s + 1] - 10.0 - z0;
            let zm = (z0 + z[s + 1] - 10.0) * 0.5;
            let along_x = Spec::Block {
                size: [bx as u32 - 20, 80, h as u32],
                mat: clad_mat,
            };
            let along_y = Spec::Block {
                size: [80, by as u32 - 20, h as u32],
                mat: clad_mat,
            };
            for i in 0..nx {
                let x = xs(i) + bx * 0.5;
                let opening = exits.contains(&i) || (s == 0 && i == door);
                if !opening {
                    plan.put(area, System::Clad, along_x, at(x, -210.0, zm));
                }
                plan.put(area, System::Clad, along_x, at(x, d + 210.0, zm));
            }
            for j in 0..ny {
                let y = ys(j) + by * 0.5;
                plan.put(area, System::Clad, along_y, at(-210.0, y, zm));
                if j > 0 {
                    plan.put(area, System::Clad, along_y, at(w + 210.0, y, zm));
                }
            }
        }
    }

    // Edge protection: a parapet on clad buildings, handrails on open ones.
    for (l, &zl) in z.iter().enumerate().skip(1) {
        let area = level_area(l);
        if clad && l == storeys {
            let zp = zl + 450.0;
            for i in 0..nx {
                let spec = Spec::Block {
                    size: [bx as u32, 200, 900],
                    mat: Mat::Concrete,
                };
                plan.put(area, System::Struct, spec, at(xs(i) + bx * 0.5, 100.0, zp));
                plan.put(
                    area,
                    System::Struct,
                    spec,
                    at(xs(i) + bx * 0.5, d - 100.0, zp),
                );
            }
            for j in 0..ny {
                let spec = Spec::Block {
                    size: [200, by as u32 - 400, 900],
                    mat: Mat::Concrete,
                };
                plan.put(area, System::Struct, spec, at(100.0, ys(j) + by * 0.5, zp));
                plan.put(
                    area,
                    System::Struct,
                    spec,
                    at(w - 100.0, ys(j) + by * 0.5, zp),
                );
            }
        } else if !clad {
            let half_turn = DMat3::from_cols(DVec3::NEG_X, DVec3::NEG_Y, DVec3::Z);
            let across = DMat3::from_cols(DVec3::NEG_Y, DVec3::X, DVec3::Z);
            for i in 0..nx {
                let spec = Spec::Handrail {
                    len: bx as u32 - 400,
                };
                plan.put(area, System::Access, spec, at(xs(i) + bx * 0.5, 200.0, zl));
                plan.put(
                    area,
                    System::Access,
                    spec,
                    place(half_turn, DVec3::new(xs(i) + bx * 0.5, d - 200.0, zl)),
                );
            }
            for j in 0..ny {
                // Shorter than the front and back ones: clear of them at the corners.
                let spec = Spec::Handrail {
                    len: by as u32 - 800,
                };
                plan.put(
                    area,
                    System::Access,
                    spec,
                    place(ALONG_Y, DVec3::new(200.0, ys(j) + by * 0.5, zl)),
                );
                if j > 0 {
                    plan.put(
                        area,
                        System::Access,
                        spec,
                        place(across, DVec3::new(w - 200.0, ys(j) + by * 0.5, zl)),
                    );
                }
            }
        }
    }

    // Rooftop plant.
    let zr = z[storeys];
    for j in 0..ny {
        for i in 0..nx {
            let (x, y) = (xs(i) + bx * 0.5, ys(j) + by * 0.5);
            let roll = rng.unit();
            if roll < 0.3 {
                let l = if bx > 6000.0 && rng.chance(0.5) {
                    4800
                } else {
                    3200
                };
                plan.put(roof, System::Equip, Spec::Hvac { l }, at(x, y, zr));
            } else if roll < 0.55 {
                plan.put(roof, System::Equip, Spec::RoofFan, at(x, y, zr));
            }
        }
    }
    plan.sort();
    plan
}

/// Columns, beams, joists and bracing of storey `s`, from `z[0]` (column foot)
/// to `z[1]` (top of the beams under the next floor).
fn frame(plan: &mut UnitPlan, area: u16, s: usize, n: [usize; 2], bay: [f64; 2], z: [f64; 2]) {
    let ([nx, ny], [bx, by], [bottom, top]) = (n, bay, z);
    let (xs, ys) = (|i: usize| i as f64 * bx, |j: usize| j as f64 * by);
    let column = Spec::Profile {
        section: SEC_COLUMN,
        len: (top - bottom) as u32,
    };
    for j in 0..=ny {
        for i in 0..=nx {
            if s == 0 {
                let size = [500, 500, 30];
                plan.put(
                    area,
                    System::Struct,
                    Spec::Block {
                        size,
                        mat: Mat::Steel,
                    },
                    at(xs(i), ys(j), 15.0),
                );
            }
            plan.put(
                area,
                System::Struct,
                column,
                place(UPRIGHT, DVec3::new(xs(i), ys(j), (top + bottom) * 0.5)),
            );
        }
    }
    let beam_z = top - 225.0;
    for j in 0..=ny {
        for i in 0..nx {
            let spec = Spec::Profile {
                section: SEC_BEAM,
                len: bx as u32 - 320,
            };
            plan.put(
                area,
                System::Struct,
                spec,
                at(xs(i) + bx * 0.5, ys(j), beam_z),
            );
        }
    }
    for i in 0..=nx {
        for j in 0..ny {
            let spec = Spec::Profile {
                section: SEC_BEAM,
                len: by as u32 - 320,
            };
            plan.put(
                area,
                System::Struct,
                spec,
                place(ALONG_Y, DVec3::new(xs(i), ys(j) + by * 0.5, beam_z)),
            );
        }
    }
    for j in 0..ny {
        for i in 0..nx {
            let spec = Spec::Profile {
                section: SEC_JOIST,
                len: by as u32 - 210,
            };
            plan.put(
                area,
                System::Struct,
                spec,
                place(
                    ALONG_Y,
                    DVec3::new(xs(i) + bx * 0.5, ys(j) + by * 0.5, top - 150.0),
                ),
            );
        }
    }
    // One diagonal per storey in the middle bay of both side walls and the back wall.
    let flip = s % 2 == 1;
    // Not the last bay along Y, where the cable tray runs, and below the tray.
    let (jb, ib) = ((ny - 1) / 2, nx / 2);
    let (z0, z1) = (bottom + 400.0, top - 1000.0);
    let mut brace = |a: DVec3, b: DVec3| {
        let (a, b) = if flip {
            (DVec3::new(a.x, a.y, z1), DVec3::new(b.x, b.y, z0))
        } else {
            (a, b)
        };
        let v = b - a;
        let spec = Spec::Brace {
            len: v.length().round() as u32,
        };
        plan.put(
            area,
            System::Struct,
            spec,
            place(basis(v.normalize(), DVec3::Z), (a + b) * 0.5),
        );
    };
    for x in [0.0, nx as f64 * bx] {
        brace(
            DVec3::new(x, ys(jb) + 400.0, z0),
            DVec3::new(x, ys(jb + 1) - 400.0, z1),
        );
    }
    let yb = ny as f64 * by;
    brace(
        DVec3::new(xs(ib) + 400.0, yb, z0),
        DVec3::new(xs(ib + 1) - 400.0, yb, z1),
    );
}

/// What equipment placement needs to know of a storey.
#[derive(Clone, Copy, Debug)]
struct Storey {
    area: u16,
    /// Storey index, 0 at the ground.
    s: usize,
    scale: Scale,
    /// Bays along X and Y.
    n: [usize; 2],
    /// Bay sizes.
    bay: [f64; 2],
    /// Floor elevation.
    floor: f64,
    /// Highest nozzle face above the floor that leaves room for the pipe lanes.
    max_h: f64,
}

/// Places equipment in the bays of a storey; returns the nozzles pipes may
/// start from.
fn equipment(plan: &mut UnitPlan, rng: &mut Rng, st: &Storey) -> Vec<Nozzle> {
    let Storey {
        area,
        s,
        scale,
        n: [nx, ny],
        bay: [bx, by],
        floor,
        max_h,
    } = *st;
    let (foot_x, foot_y) = (bx - 1200.0, by - 1200.0);
    let fill = if scale == Scale::Full { 0.65 } else { 0.85 };
    let mut nozzles = Vec::new();
    let sys = System::Equip;
    for j in 0..ny {
        for i in 0..nx {
            if !rng.chance(fill) {
                continue;
            }
            let (cx, cy) = (i as f64 * bx + bx * 0.5, j as f64 * by + by * 0.5);
            let seed = rng.below(1 << 16) as u16;
            let dn = 1 + rng.below(4) as u8;
            let roll = rng.unit();
            let kind = if s == 0 { roll } else { 0.25 + roll * 0.75 };
            if kind < 0.25 {
                // A pair of pumps.
                let size = if scale == Scale::Tiny {
                    0
                } else {
                    rng.below(3) as u8
                };
                let (x0, x1) = pump_extent(size);
                let px = cx - ((x0 + x1) as f64 * 0.5 / 50.0).round() * 50.0;
                for dy in [-800.0, 800.0] {
                    plan.put(area, sys, Spec::Pump { size }, at(px, cy + dy, floor));
                    let top = f64::from(pump_top(size));
                    nozzles.push(Nozzle {
                        at: DVec3::new(px, cy + dy, floor + top),
                        dn: pump_dn(size),
                    });
                }
            } else if kind < 0.5 {
                // A vertical vessel as tall as the lanes allow.
                let d = (1000 + 200 * rng.below(8) as u32).min(foot_x.min(foot_y) as u32 - 1400);
                let room = max_h - f64::from(vessel_top(d, 0, dn));
                if room < 800.0 {
                    continue;
                }
                let h = 800 + 100 * rng.below(((room - 800.0) / 100.0) as u64 + 1) as u32;
                plan.put(
                    area,
                    sys,
                    Spec::Vessel { d, h, dn, seed },
                    at(cx, cy, floor),
                );
                nozzles.push(Nozzle {
                    at: DVec3::new(cx, cy, floor + f64::from(vessel_top(d, h, dn))),
                    dn,
                });
            } else if kind < 0.85 {
                // A drum or an exchanger along X.
                let exchanger = kind >= 0.68;
                let mut d = if exchanger {
                    500 + 100 * rng.below(6) as u32
                } else {
                    800 + 200 * rng.below(5) as u32
                };
                let l_max = foot_x as u32 - d;
                let l = 2000 + 250 * rng.below(u64::from((l_max - 2000) / 250) + 1) as u32;
                while f64::from(drum_nozzle(d, l, dn).1) > max_h && d > 500 {
                    d -= 100;
                }
                let (nx_off, top) = drum_nozzle(d, l, dn);
                if f64::from(top) > max_h {
                    continue;
                }
                let spec = if exchanger {
                    Spec::Exchanger { d, l, dn, seed }
                } else {
                    Spec::Drum { d, l, dn, seed }
                };
                plan.put(area, sys, spec, at(cx, cy, floor));
                nozzles.push(Nozzle {
                    at: DVec3::new(cx + nx_off as f64, cy, floor + f64::from(top)),
                    dn,
                });
            } else if max_h > 2300.0 {
                let w = if bx > 6000.0 {
                    4000
                } else {
                    pick(rng, &[2400, 3200])
                };
                plan.put(area, sys, Spec::Cabinet { w }, at(cx, cy, floor));
            }
        }
    }
    nozzles
}

/// Routes pipes from the nozzles, one lane each: to another nozzle of the same
/// size when the way is clear, or out through the front wall. Returns the bay
/// columns whose front cladding the pipes pass through.
fn routes(
    plan: &mut UnitPlan,
    rng: &mut Rng,
    area: u16,
    nozzles: &[Nozzle],
    bx: f64,
    lanes: std::ops::Range<usize>,
    lane_z: impl Fn(usize) -> f64,
) -> Vec<usize> {
    // Vertical pipes so far: (x, y, lane). A horizontal run must keep clear of
    // those ending in a higher lane, since they pass through its elevation.
    let mut risers: Vec<(f64, f64, usize)> = Vec::new();
    let mut used = vec![false; nozzles.len()];
    let mut exits = Vec::new();
    let mut lane = lanes.start;
    for a in 0..nozzles.len() {
        if lane >= lanes.end {
            break;
        }
        if used[a] {
            continue;
        }
        let na = nozzles[a];
        let zl = lane_z(lane);
        let rise = DVec3::new(na.at.x, na.at.y, zl);
        let target = (a + 1..nozzles.len())
            .find(|&b| !used[b] && nozzles[b].dn == na.dn)
            .filter(|_| rng.chance(0.4));
        let (points, end, exit) = match target {
            Some(b) => {
                let nb = nozzles[b].at;
                let points = vec![
                    na.at,
                    rise,
                    DVec3::new(nb.x, na.at.y, zl),
                    DVec3::new(nb.x, nb.y, zl),
                    nb,
                ];
                (points, End::Nozzle, None)
            }
            None => {
                let col = (na.at.x / bx).floor();
                let xc = col * bx + 900.0;
                let points = vec![
                    na.at,
                    rise,
                    DVec3::new(xc, na.at.y, zl),
                    DVec3::new(xc, -1500.0, zl),
                ];
                (points, End::Blind, Some(col as usize))
            }
        };
        let clear = points
            .windows(2)
            .filter(|p| p[0].z == zl && p[1].z == zl)
            .all(|p| {
                risers
                    .iter()
                    .all(|&(x, y, l)| l >= lane || distance_to_segment(x, y, p[0], p[1]) > 450.0)
            });
        if !clear {
            continue;
        }
        let route = Route {
            dn: na.dn,
            mat: pick(rng, &SERVICES),
            points,
            start: End::Nozzle,
            end,
            valve_leg: rng
                .chance(0.7)
                .then_some(if rng.chance(0.5) { 0 } else { 1 }),
        };
        if plan.pipe(area, &route).is_some() {
            used[a] = true;
            risers.push((na.at.x, na.at.y, lane));
            if let Some(b) = target {
                used[b] = true;
                risers.push((nozzles[b].at.x, nozzles[b].at.y, lane));
            }
            exits.extend(exit);
            lane += 1;
        }
    }
    exits
}

/// Distance in plan from (x, y) to the horizontal segment a-b (axis-aligned).
fn distance_to_segment(x: f64, y: f64, a: DVec3, b: DVec3) -> f64 {
    let (lo, hi) = (a.min(b), a.max(b));
    let dx = (lo.x - x).max(x - hi.x).max(0.0);
    let dy = (lo.y - y).max(y - hi.y).max(0.0);
    dx.hypot(dy)
}
