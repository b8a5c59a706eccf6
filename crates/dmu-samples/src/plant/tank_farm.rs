//! A tank farm: four storage tanks on plinths inside a bund wall, each with a
//! caged ladder to a roof landing and an outlet pipe over the bund towards the
//! rack. Large, simple occluders with open space between them.

use glam::DVec3;

use super::catalog::{DNS, Mat, SERVICES, Spec};
use super::unit::{End, Route, System, UnitPlan, at};
use crate::Rng;

/// Distance from the plot's front to the farm's origin (the bund's front side
/// is 500 mm behind it).
const FRONT: f64 = 14_000.0;
/// Outlet nozzle size (index into the pipe sizes) and its height above the tank floor.
const OUTLET: (u8, f64) = (5, 600.0);
/// Plinth height.
const PLINTH: f64 = 300.0;

/// Plans a tank farm for a plot `plot_x` wide.
pub(super) fn tank_farm(rng: &mut Rng, plot_x: f64) -> UnitPlan {
    let mut plan = UnitPlan::new(DVec3::ZERO.with_y(FRONT));
    let (x0, x1, y0, y1) = (1000.0, plot_x - 1000.0, 500.0, 29_500.0);
    let mid = plot_x * 0.5;
    let centres = [
        (mid - 11_000.0, 8000.0),
        (mid + 11_000.0, 8000.0),
        (mid - 11_000.0, 22_000.0),
        (mid + 11_000.0, 22_000.0),
    ];
    let sizes: Vec<(f64, f64)> = centres
        .iter()
        .map(|_| {
            (
                6000.0 + 500.0 * rng.below(13) as f64,
                6000.0 + 500.0 * rng.below(17) as f64,
            )
        })
        .collect();
    let front_r = |k: usize| sizes[k % 2].0 * 0.5;
    for (k, (&(cx, cy), &(d, h))) in centres.iter().zip(&sizes).enumerate() {
        let area = plan.area(format!("TK{}", k + 1), PLINTH);
        let r = d * 0.5;
        plan.put(
            area,
            System::Struct,
            Spec::Plinth {
                d: d as u32 + 1000,
                h: PLINTH as u32,
            },
            at(cx, cy, PLINTH),
        );
        plan.put(
            area,
            System::Equip,
            Spec::Tank {
                d: d as u32,
                h: h as u32,
            },
            at(cx, cy, PLINTH),
        );
        // Caged ladder on the +X side up to a roof landing.
        let top = PLINTH + h;
        plan.put(
            area,
            System::Access,
            Spec::Ladder { h: h as u32 },
            at(cx + r + 1200.0, cy, PLINTH),
        );
        plan.put(
            area,
            System::Access,
            Spec::Block {
                size: [1050, 1500, 40],
                mat: Mat::Grating,
            },
            at(cx + r + 575.0, cy, top - 20.0),
        );
        for side in [-1.0, 1.0] {
            plan.put(
                area,
                System::Access,
                Spec::Handrail { len: 1000 },
                at(cx + r + 600.0, cy + side * 700.0, top),
            );
        }
        // The outlet: out of the bund towards the rack; back tanks go round the front ones.
        let (dn, zo) = (OUTLET.0, PLINTH + OUTLET.1);
        let p = DNS[dn as usize];
        let face = cy - r - 200.0 - f64::from(p.flange_len);
        // Rise just behind the bund, cross it well above its top.
        let (z_over, y_in) = (2400.0, y0 + 500.0);
        let points = if k < 2 {
            vec![
                DVec3::new(cx, face, zo),
                DVec3::new(cx, y_in, zo),
                DVec3::new(cx, y_in, z_over),
                DVec3::new(cx, -2000.0, z_over),
            ]
        } else {
            let y_mid = ((cy - r + centres[k - 2].1 + front_r(k)) * 0.5).round();
            let x_side = mid + if k == 2 { -600.0 } else { 600.0 };
            vec![
                DVec3::new(cx, face, zo),
                DVec3::new(cx, y_mid, zo),
                DVec3::new(x_side, y_mid, zo),
                DVec3::new(x_side, y_in, zo),
                DVec3::new(x_side, y_in, z_over),
                DVec3::new(x_side, -2000.0, z_over),
            ]
        };
        let route = Route {
            dn,
            mat: SERVICES[rng.below(SERVICES.len() as u64) as usize],
            points,
            start: End::Nozzle,
            end: End::Blind,
            valve_leg: Some(0),
        };
        // The legs are laid out long enough for the fittings.
        let planned = plan.pipe(area, &route);
        debug_assert!(planned.is_some(), "tank outlet {k} does not fit");
    }
    // The bund wall, in panels about 6 m long.
    let bund = plan.area("BND", 0.0);
    let wall = |plan: &mut UnitPlan, a: DVec3, b: DVec3| {
        let len = a.distance(b);
        let panels = (len / 6000.0).ceil();
        let step = (b - a) / panels;
        let along_x = (b - a).x.abs() > 0.0;
        let piece = (len / panels).round() as u32 - 20;
        let size = if along_x {
            [piece, 300, 1200]
        } else {
            [300, piece, 1200]
        };
        for k in 0..panels as usize {
            let c = a + step * (k as f64 + 0.5);
            plan.put(
                bund,
                System::Struct,
                Spec::Block {
                    size,
                    mat: Mat::Concrete,
                },
                at(c.x, c.y, 600.0),
            );
        }
    };
    wall(&mut plan, DVec3::new(x0, y0, 0.0), DVec3::new(x1, y0, 0.0));
    wall(&mut plan, DVec3::new(x0, y1, 0.0), DVec3::new(x1, y1, 0.0));
    wall(
        &mut plan,
        DVec3::new(x0, y0 + 170.0, 0.0),
        DVec3::new(x0, y1 - 170.0, 0.0),
    );
    wall(
        &mut plan,
        DVec3::new(x1, y0 + 170.0, 0.0),
        DVec3::new(x1, y1 - 170.0, 0.0),
    );
    plan.sort();
    plan
}
