//! A pipe rack section running along X in front of a plot: bents of two columns
//! every 6 m, two or three tiers of pipes resting on shoes, and a cable tray
//! tier on top. Sections of neighbouring plots line up into one long rack, and
//! their pipes continue across (each section owns the joint at its start).

use glam::DVec3;

use super::Scale;
use super::catalog::{
    DNS, Mat, SEC_COLUMN, SEC_JOIST, SEC_RACK, SERVICES, SHOE_H, Spec, flange_pair_len,
};
use super::unit::{ALONG_Y, System, UPRIGHT, UnitPlan, at, basis, place};
use crate::Rng;

/// Distance from the plot's front to the rack's first column line.
const FRONT: f64 = 2_000.0;
/// Bent spacing.
const BAY: f64 = 6_000.0;
/// Length of the welded pipe pieces.
const SPOOL: f64 = 12_000.0;

/// Plans a rack section as long as the plot.
pub(super) fn rack(rng: &mut Rng, scale: Scale, plot_x: f64) -> UnitPlan {
    let width = [6000.0, 7000.0, 8000.0][rng.below(3) as usize];
    let tiers = if scale == Scale::Tiny {
        1
    } else {
        2 + rng.below(2) as usize
    };
    let bays = (plot_x / BAY) as usize;
    let length = bays as f64 * BAY;
    let mut zt: Vec<f64> = (0..tiers).map(|t| 5000.0 + 2000.0 * t as f64).collect();
    zt.push(zt[tiers - 1] + 1500.0);
    let mut plan = UnitPlan::new(DVec3::new(0.0, FRONT, 0.0));
    let bent = |k: usize| BAY * 0.5 + BAY * k as f64;

    for (t, &top) in zt.iter().enumerate() {
        let name = if t < tiers {
            format!("T{}", t + 1)
        } else {
            "E1".into()
        };
        let area = plan.area(name, top);
        let bottom = if t == 0 { 30.0 } else { zt[t - 1] };
        let column = Spec::Profile {
            section: SEC_COLUMN,
            len: (top - bottom) as u32,
        };
        let tier_beam = Spec::Profile {
            section: SEC_RACK,
            len: width as u32 - 320,
        };
        let strut = Spec::Profile {
            section: SEC_JOIST,
            len: BAY as u32 - 320,
        };
        for k in 0..bays {
            let x = bent(k);
            for y in [0.0, width] {
                if t == 0 {
                    let size = [500, 500, 30];
                    plan.put(
                        area,
                        System::Struct,
                        Spec::Block {
                            size,
                            mat: Mat::Steel,
                        },
                        at(x, y, 15.0),
                    );
                }
                plan.put(
                    area,
                    System::Struct,
                    column,
                    place(UPRIGHT, DVec3::new(x, y, (top + bottom) * 0.5)),
                );
                plan.put(
                    area,
                    System::Struct,
                    strut,
                    at(x + BAY * 0.5, y, top - 150.0),
                );
            }
            plan.put(
                area,
                System::Struct,
                tier_beam,
                place(ALONG_Y, DVec3::new(x, width * 0.5, top - 145.0)),
            );
        }
        if t == 0 {
            let k = bays / 2 - 1;
            for y in [0.0, width] {
                let (a, b) = (
                    DVec3::new(bent(k) + 400.0, y, 400.0),
                    DVec3::new(bent(k + 1) - 400.0, y, top - 750.0),
                );
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
            }
        }

        if t < tiers {
            // Pipes side by side, flanges clear of each other, on shoes at every bent.
            let mut y = 350.0;
            loop {
                let dn = [1u8, 2, 2, 3, 3, 3, 4, 4, 5, 5, 6, 7, 8, 9][rng.below(14) as usize];
                let p = DNS[dn as usize];
                let rf = f64::from(p.flange_od) * 0.5;
                if y + 2.0 * rf > width - 350.0 {
                    break;
                }
                let yc = (y + rf).round();
                y = yc + rf + 100.0;
                let zc = top + f64::from(SHOE_H) + f64::from(p.od) * 0.5;
                let mat = SERVICES[rng.below(SERVICES.len() as u64) as usize];
                // Welded 12 m lengths; now and then a flanged joint where the section starts.
                let joint = rng.chance(0.25);
                let mut x = 0.0;
                if joint {
                    let fp = f64::from(flange_pair_len(dn));
                    plan.put(
                        area,
                        System::Pipe,
                        Spec::FlangePair { dn, mat },
                        at(fp * 0.5, yc, zc),
                    );
                    x = fp;
                }
                while x < length {
                    let end = ((x / SPOOL).floor() + 1.0) * SPOOL;
                    let end = end.min(length);
                    let spec = Spec::Pipe {
                        dn,
                        len: (end - x) as u32,
                        mat,
                    };
                    plan.put(area, System::Pipe, spec, at((x + end) * 0.5, yc, zc));
                    x = end;
                }
                for k in (0..bays).step_by(2) {
                    plan.put(area, System::Pipe, Spec::Shoe { dn }, at(bent(k), yc, zc));
                }
            }
        } else {
            let mut y = 500.0;
            loop {
                let w = [300u32, 450, 600][rng.below(3) as usize];
                if y + f64::from(w) > width - 500.0 {
                    break;
                }
                let yc = y + f64::from(w) * 0.5 + 60.0;
                y = yc + f64::from(w) * 0.5 + 250.0;
                for k in 0..bays {
                    plan.put(
                        area,
                        System::Elec,
                        Spec::Tray {
                            len: BAY as u32 - 40,
                            w,
                        },
                        at(bent(k), yc, top),
                    );
                }
            }
        }
    }
    plan.sort();
    plan
}
