//! The plant's parts catalogue: every mesh is named by a [`Spec`] of integer
//! millimetre dimensions, so equal specs share one mesh the way CAD assemblies
//! share standard parts, and tessellated by [`build`] at the scene's [`Detail`].
//!
//! Local frames: linear parts (beams, pipes, trays, handrails) run along local X
//! and are centred on their origin; elbows have their corner at the origin (in
//! along +X, out along +Y); equipment, ladders and supports stand on their
//! origin with Z up.

use std::f32::consts::{FRAC_1_SQRT_2, FRAC_PI_2, PI, TAU};

use glam::{Affine3A, Mat3, Vec3};

use crate::shapes::{Tess, along, c_section, frame, i_section};
use dmu_scene::MaterialId;
use dmu_scene::MeshData;

/// Materials, in the order the plant adds them (so `Mat as u32` is the id).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(super) enum Mat {
    Steel,
    Concrete,
    Grating,
    Cladding,
    CladdingAlt,
    PipeProcess,
    PipeWater,
    PipeSteam,
    PipeFire,
    PipeGas,
    PipeChemical,
    Valve,
    Vessel,
    Pump,
    Motor,
    Cabinet,
    Tray,
    Safety,
    Hvac,
    Tank,
    Light,
}

/// Names and linear base colours, indexed by [`Mat`].
pub(super) const MATERIALS: [(&str, [f32; 4]); 21] = [
    ("structural steel", [0.42, 0.45, 0.50, 1.0]),
    ("concrete", [0.62, 0.61, 0.58, 1.0]),
    ("grating", [0.30, 0.31, 0.33, 1.0]),
    ("cladding", [0.32, 0.42, 0.52, 1.0]),
    ("cladding alt", [0.55, 0.57, 0.52, 1.0]),
    ("pipe process", [0.55, 0.55, 0.57, 1.0]),
    ("pipe cooling water", [0.12, 0.42, 0.20, 1.0]),
    ("pipe steam", [0.80, 0.80, 0.78, 1.0]),
    ("pipe fire water", [0.70, 0.08, 0.06, 1.0]),
    ("pipe gas", [0.85, 0.65, 0.05, 1.0]),
    ("pipe chemical", [0.72, 0.35, 0.10, 1.0]),
    ("valve", [0.55, 0.10, 0.12, 1.0]),
    ("vessel", [0.78, 0.80, 0.82, 1.0]),
    ("pump", [0.10, 0.25, 0.60, 1.0]),
    ("motor", [0.20, 0.35, 0.25, 1.0]),
    ("cabinet", [0.70, 0.70, 0.66, 1.0]),
    ("cable tray", [0.66, 0.68, 0.70, 1.0]),
    ("safety yellow", [0.90, 0.70, 0.05, 1.0]),
    ("hvac", [0.60, 0.62, 0.64, 1.0]),
    ("storage tank", [0.88, 0.88, 0.86, 1.0]),
    ("light", [0.95, 0.95, 0.85, 1.0]),
];

impl Mat {
    /// The material's id in the plant scene.
    pub(super) fn id(self) -> MaterialId {
        MaterialId(self as u32)
    }
}

/// Pipe services, each with its colour.
pub(super) const SERVICES: [Mat; 6] = [
    Mat::PipeProcess,
    Mat::PipeWater,
    Mat::PipeSteam,
    Mat::PipeFire,
    Mat::PipeGas,
    Mat::PipeChemical,
];

/// A nominal pipe size (ASME B36.10 outside diameter, long-radius elbow,
/// class 150 weld-neck flange and gate valve), in millimetres.
#[derive(Clone, Copy, Debug)]
pub(super) struct Dn {
    /// Nominal size, for names.
    pub nominal: u32,
    /// Outside diameter.
    pub od: f32,
    /// Elbow centre-line radius: the elbow ends this far from the corner.
    pub bend: u32,
    /// Flange outside diameter.
    pub flange_od: f32,
    /// Flange length along the pipe (hub and disc).
    pub flange_len: u32,
    /// Valve face-to-face length.
    pub valve_len: u32,
    /// Bolts per flange.
    pub bolts: u32,
}

const fn dn(
    nominal: u32,
    od: f32,
    bend: u32,
    flange_od: f32,
    flange_len: u32,
    valve_len: u32,
    bolts: u32,
) -> Dn {
    Dn {
        nominal,
        od,
        bend,
        flange_od,
        flange_len,
        valve_len,
        bolts,
    }
}

/// The pipe sizes in use, smallest first.
pub(super) const DNS: [Dn; 10] = [
    dn(50, 60.3, 76, 152.0, 62, 178, 4),
    dn(80, 88.9, 114, 190.0, 68, 203, 4),
    dn(100, 114.3, 152, 229.0, 75, 229, 8),
    dn(150, 168.3, 229, 279.0, 88, 267, 8),
    dn(200, 219.1, 305, 343.0, 100, 292, 8),
    dn(250, 273.0, 381, 406.0, 100, 330, 12),
    dn(300, 323.9, 457, 483.0, 113, 356, 12),
    dn(400, 406.4, 610, 597.0, 125, 406, 16),
    dn(500, 508.0, 762, 699.0, 144, 457, 20),
    dn(600, 610.0, 914, 813.0, 152, 508, 20),
];

/// Length of a bolted flange pair (two flanges and a 3 mm gasket).
pub(super) fn flange_pair_len(dn: u8) -> u32 {
    2 * DNS[dn as usize].flange_len + 3
}

/// Structural sections: (depth h, width b, web, flange), millimetres.
pub(super) const SECTIONS: [(f32, f32, f32, f32); 4] = [
    // HEB 300 column.
    (300.0, 300.0, 11.0, 19.0),
    // IPE 450 main beam.
    (450.0, 190.0, 9.4, 14.6),
    // IPE 300 joist.
    (300.0, 150.0, 7.1, 10.7),
    // HEA 300 rack beam.
    (290.0, 300.0, 8.5, 14.0),
];
/// Index of the column section in [`SECTIONS`].
pub(super) const SEC_COLUMN: u8 = 0;
/// Index of the main beam section.
pub(super) const SEC_BEAM: u8 = 1;
/// Index of the joist section.
pub(super) const SEC_JOIST: u8 = 2;
/// Index of the rack beam section.
pub(super) const SEC_RACK: u8 = 3;

/// Tessellation detail, chosen from the scene's triangle target.
#[derive(Clone, Copy, Debug)]
pub(super) struct Detail {
    /// Segments around a round of radius 100 mm; others scale with the square
    /// root of their radius, as a chord-error tessellator would.
    pub seg: u32,
    /// Steps along a 90° elbow.
    pub steps: u32,
    /// Rings of a vessel head.
    pub rings: u32,
    /// Flange bolts, ladder cages, handwheel spokes and similar small detail.
    pub fine: bool,
}

impl Detail {
    /// Segments around a round of radius `r` millimetres.
    pub(super) fn seg(&self, r: f32) -> u32 {
        let s = (self.seg as f32 * (r / 100.0).sqrt()).round() as u32;
        (s.clamp(6, 4 * self.seg) + 1) & !1
    }
}

/// One catalogue mesh: its kind and integer millimetre dimensions.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(super) enum Spec {
    /// A box of `size` (x, y, z), centred.
    Block { size: [u32; 3], mat: Mat },
    /// A rolled section (index into [`SECTIONS`]) along X, `len` long.
    Profile { section: u8, len: u32 },
    /// A 150×150 square hollow section along X.
    Brace { len: u32 },
    /// A straight pipe along X.
    Pipe { dn: u8, len: u32, mat: Mat },
    /// A 90° long-radius elbow, corner at the origin, in +X, out +Y.
    Elbow { dn: u8, mat: Mat },
    /// One weld-neck flange along X, hub towards -X, face at +X.
    Flange { dn: u8, mat: Mat },
    /// Two bolted flanges (a pipe joint or a blind end).
    FlangePair { dn: u8, mat: Mat },
    /// A gate valve along X with its stem up +Z.
    Valve { dn: u8 },
    /// A vertical vessel on a skirt, top nozzle of size `dn`; `seed` places the
    /// side nozzles.
    Vessel { d: u32, h: u32, dn: u8, seed: u16 },
    /// A horizontal drum on two saddles along X.
    Drum { d: u32, l: u32, dn: u8, seed: u16 },
    /// A shell-and-tube heat exchanger along X.
    Exchanger { d: u32, l: u32, dn: u8, seed: u16 },
    /// An end-suction pump with its motor along +X; size 0..3.
    Pump { size: u8 },
    /// An electrical cabinet row `w` wide along X.
    Cabinet { w: u32 },
    /// A rooftop air handling unit `l` long along X.
    Hvac { l: u32 },
    /// A rooftop exhaust fan.
    RoofFan,
    /// A ceiling light.
    Light,
    /// A ladder `h` high in the YZ plane, its cage towards +X.
    Ladder { h: u32 },
    /// A handrail along X, `len` long, standing on z = 0.
    Handrail { len: u32 },
    /// A ladder-type cable tray along X, `w` wide, bottom at z = 0.
    Tray { len: u32, w: u32 },
    /// A trapeze hanger for a tray `w` wide: two rods `drop` long above z = 0.
    TraySupport { w: u32, drop: u32 },
    /// A pipe hanger: a clamp round the pipe at the origin and a rod `drop` long
    /// up from the pipe's top.
    Hanger { dn: u8, drop: u32 },
    /// A pipe shoe under a pipe centred at the origin, on a beam below.
    Shoe { dn: u8 },
    /// A vertical storage tank with a cone roof, standing on z = 0.
    Tank { d: u32, h: u32 },
    /// A round concrete plinth, top at z = 0.
    Plinth { d: u32, h: u32 },
}

/// Height of a shoe: the pipe's bottom sits this far above the beam.
pub(super) const SHOE_H: f32 = 100.0;
/// Height of a vessel's skirt.
pub(super) fn vessel_skirt(d: u32) -> u32 {
    if d >= 1600 { 1000 } else { 700 }
}
/// Length of a nozzle stub (shell to flange hub).
const NOZZLE: f32 = 200.0;

/// Where a vertical vessel's top nozzle face is, above its base.
pub(super) fn vessel_top(d: u32, h: u32, dn: u8) -> u32 {
    vessel_skirt(d) + h + d / 4 + NOZZLE as u32 + DNS[dn as usize].flange_len
}
/// The top nozzle of a drum: (x along its axis, height of the face).
pub(super) fn drum_nozzle(d: u32, l: u32, dn: u8) -> (i64, u32) {
    (
        i64::from(l / 4),
        drum_axis(d) + d / 2 + NOZZLE as u32 + DNS[dn as usize].flange_len,
    )
}
fn drum_axis(d: u32) -> u32 {
    d / 2 + 500
}
/// Size of the discharge nozzle of a pump of `size`.
pub(super) fn pump_dn(size: u8) -> u8 {
    [1, 2, 3][size as usize]
}
/// Pump casing radius and shaft height.
fn pump_casing(size: u8) -> (f32, f32) {
    let r = [160.0, 210.0, 270.0][size as usize];
    (r, r + 350.0)
}
/// The discharge nozzle face height of a pump (the nozzle is at x = y = 0).
pub(super) fn pump_top(size: u8) -> u32 {
    let (r, axis) = pump_casing(size);
    (axis + r) as u32 + NOZZLE as u32 + DNS[pump_dn(size) as usize].flange_len
}
/// Footprint of a pump and motor along X: (from, to).
pub(super) fn pump_extent(size: u8) -> (i64, i64) {
    let (r, _) = pump_casing(size);
    (-(r as i64) - 450, [1300, 1700, 2200][size as usize])
}

impl Spec {
    /// A readable mesh name.
    pub(super) fn name(&self) -> String {
        match *self {
            Self::Block {
                size: [x, y, z],
                mat,
            } => format!("BLOCK-{x}x{y}x{z}-{mat:?}"),
            Self::Profile { section, len } => format!(
                "{}-L{len}",
                ["HEB300", "IPE450", "IPE300", "HEA300"][section as usize]
            ),
            Self::Brace { len } => format!("SHS150-L{len}"),
            Self::Pipe { dn, len, mat } => {
                format!("PIPE-DN{}-L{len}-{mat:?}", DNS[dn as usize].nominal)
            }
            Self::Elbow { dn, mat } => format!("ELBOW90-DN{}-{mat:?}", DNS[dn as usize].nominal),
            Self::Flange { dn, mat } => format!("FLANGE-DN{}-{mat:?}", DNS[dn as usize].nominal),
            Self::FlangePair { dn, mat } => format!("JOINT-DN{}-{mat:?}", DNS[dn as usize].nominal),
            Self::Valve { dn } => format!("GATE-VALVE-DN{}", DNS[dn as usize].nominal),
            Self::Vessel { d, h, seed, .. } => format!("VESSEL-D{d}-H{h}-{seed}"),
            Self::Drum { d, l, seed, .. } => format!("DRUM-D{d}-L{l}-{seed}"),
            Self::Exchanger { d, l, seed, .. } => format!("EXCHANGER-D{d}-L{l}-{seed}"),
            Self::Pump { size } => format!("PUMP-{size}"),
            Self::Cabinet { w } => format!("CABINET-W{w}"),
            Self::Hvac { l } => format!("AHU-L{l}"),
            Self::RoofFan => "ROOF-FAN".into(),
            Self::Light => "LIGHT".into(),
            Self::Ladder { h } => format!("LADDER-H{h}"),
            Self::Handrail { len } => format!("HANDRAIL-L{len}"),
            Self::Tray { len, w } => format!("TRAY-W{w}-L{len}"),
            Self::TraySupport { w, drop } => format!("TRAY-HANGER-W{w}-D{drop}"),
            Self::Hanger { dn, drop } => {
                format!("PIPE-HANGER-DN{}-D{drop}", DNS[dn as usize].nominal)
            }
            Self::Shoe { dn } => format!("PIPE-SHOE-DN{}", DNS[dn as usize].nominal),
            Self::Tank { d, h } => format!("TANK-D{d}-H{h}"),
            Self::Plinth { d, h } => format!("PLINTH-D{d}-H{h}"),
        }
    }
}

/// Tessellates a catalogue mesh.
pub(super) fn build(spec: &Spec, detail: &Detail) -> MeshData {
    let mut t = Tess::new(spec.name(), Mat::Steel.id());
    let d = detail;
    match *spec {
        Spec::Block { size, mat } => {
            t.material = mat.id();
            t.block(Vec3::ZERO, v3(size));
        }
        Spec::Profile { section, len } => {
            let (h, b, tw, tf) = SECTIONS[section as usize];
            let (outline, cap) = i_section(h, b, tw, tf);
            let half = len as f32 * 0.5;
            t.extrude(&outline, &cap, -half, half);
        }
        Spec::Brace { len } => {
            let half = len as f32 * 0.5;
            t.cuboid(Vec3::new(-half, -75.0, -75.0), Vec3::new(half, 75.0, 75.0));
        }
        Spec::Pipe { dn, len, mat } => {
            t.material = mat.id();
            let r = DNS[dn as usize].od * 0.5;
            let half = len as f32 * 0.5;
            t.cylinder(-half, half, r, d.seg(r));
        }
        Spec::Elbow { dn, mat } => {
            t.material = mat.id();
            let p = DNS[dn as usize];
            let (bend, r) = (p.bend as f32, p.od * 0.5);
            // The torus starts at (bend, 0, 0) heading +Y: turn it so it starts at
            // (-bend, 0, 0) heading +X and ends at (0, bend, 0) heading +Y.
            t.xf = Affine3A::from_mat3_translation(
                Mat3::from_cols(-Vec3::Y, Vec3::X, Vec3::Z),
                Vec3::new(-bend, bend, 0.0),
            );
            t.torus(bend, r, FRAC_PI_2, d.steps, d.seg(r), true);
        }
        Spec::Flange { dn, mat } => {
            t.material = mat.id();
            let len = DNS[dn as usize].flange_len as f32;
            flange(&mut t, d, dn, -len * 0.5, 1.0);
        }
        Spec::FlangePair { dn, mat } => {
            t.material = mat.id();
            let len = DNS[dn as usize].flange_len as f32;
            // Faces meet at the origin across the gasket.
            flange(&mut t, d, dn, -len - 1.5, 1.0);
            flange(&mut t, d, dn, len + 1.5, -1.0);
        }
        Spec::Valve { dn } => valve(&mut t, d, dn),
        Spec::Vessel {
            d: dia,
            h,
            dn,
            seed,
        } => vessel(&mut t, d, dia, h, dn, seed),
        Spec::Drum {
            d: dia,
            l,
            dn,
            seed,
        } => drum(&mut t, d, dia, l, dn, seed, false),
        Spec::Exchanger {
            d: dia,
            l,
            dn,
            seed,
        } => drum(&mut t, d, dia, l, dn, seed, true),
        Spec::Pump { size } => pump(&mut t, d, size),
        Spec::Cabinet { w } => cabinet(&mut t, w),
        Spec::Hvac { l } => hvac(&mut t, d, l),
        Spec::RoofFan => {
            t.material = Mat::Hvac.id();
            t.block(Vec3::new(0.0, 0.0, 50.0), Vec3::new(1000.0, 1000.0, 100.0));
            t.xf = frame(Vec3::ZERO, Vec3::Z, Vec3::X);
            t.cylinder(100.0, 700.0, 400.0, d.seg(400.0));
            t.frustum(700.0, 1000.0, 480.0, 60.0, d.seg(480.0), (true, true));
        }
        Spec::Light => {
            t.material = Mat::Steel.id();
            t.block(Vec3::new(0.0, 0.0, -40.0), Vec3::new(1250.0, 160.0, 80.0));
            t.material = Mat::Light.id();
            t.block(Vec3::new(0.0, 0.0, -95.0), Vec3::new(1200.0, 110.0, 30.0));
        }
        Spec::Ladder { h } => ladder(&mut t, d, h),
        Spec::Handrail { len } => handrail(&mut t, d, len),
        Spec::Tray { len, w } => tray(&mut t, d, len, w),
        Spec::TraySupport { w, drop } => {
            t.material = Mat::Tray.id();
            let (w, drop) = (w as f32, drop as f32);
            t.block(Vec3::new(0.0, 0.0, -20.0), Vec3::new(60.0, w + 200.0, 40.0));
            t.xf = frame(Vec3::ZERO, Vec3::Z, Vec3::X);
            for y in [-(w * 0.5 + 60.0), w * 0.5 + 60.0] {
                t.xf.translation = Vec3::new(0.0, y, 0.0).into();
                t.cylinder(-40.0, drop, 6.0, d.seg(6.0));
            }
        }
        Spec::Hanger { dn, drop } => {
            let r = DNS[dn as usize].od * 0.5;
            t.material = Mat::Steel.id();
            // A clamp ring round the pipe (in the YZ plane) and a rod up.
            t.xf = frame(Vec3::ZERO, Vec3::Y, Vec3::Z);
            t.torus(r + 8.0, 6.0, TAU, d.seg(r + 8.0), 6, false);
            t.xf = frame(Vec3::ZERO, Vec3::Z, Vec3::X);
            t.cylinder(r + 14.0, r + 14.0 + drop as f32, 8.0, d.seg(8.0));
        }
        Spec::Shoe { dn } => {
            let r = DNS[dn as usize].od * 0.5;
            let w = (r * 1.2).max(100.0);
            t.block(
                Vec3::new(0.0, 0.0, -r - SHOE_H + 8.0),
                Vec3::new(300.0, w, 16.0),
            );
            t.block(
                Vec3::new(0.0, 0.0, -r - SHOE_H * 0.5 - 1.0),
                Vec3::new(300.0, 12.0, SHOE_H - 18.0),
            );
        }
        Spec::Tank { d: dia, h } => tank(&mut t, d, dia, h),
        Spec::Plinth { d: dia, h } => {
            t.material = Mat::Concrete.id();
            let r = dia as f32 * 0.5;
            t.xf = frame(Vec3::ZERO, Vec3::Z, Vec3::X);
            t.cylinder(-(h as f32), 0.0, r, d.seg(r));
        }
    }
    t.finish()
}

fn v3(size: [u32; 3]) -> Vec3 {
    Vec3::new(size[0] as f32, size[1] as f32, size[2] as f32)
}

/// A weld-neck flange along X: its hub (pipe) end at `x_hub`, its face at
/// `x_hub + dir * flange_len` (`dir` is +1 or -1).
fn flange(t: &mut Tess, d: &Detail, dn: u8, x_hub: f32, dir: f32) {
    let p = DNS[dn as usize];
    let (r, rf, len) = (p.od * 0.5, p.flange_od * 0.5, p.flange_len as f32);
    let disc = (len * 0.4).max(14.0);
    let r_hub = r * 1.12 + 6.0;
    // In the flange's own axis u (from hub end to face): hub [0, len - disc], disc after.
    let span = |u0: f32, u1: f32| {
        if dir > 0.0 {
            (x_hub + u0, x_hub + u1)
        } else {
            (x_hub - u1, x_hub - u0)
        }
    };
    let (a, b) = span(0.0, len - disc);
    let (ra, rb) = if dir > 0.0 { (r, r_hub) } else { (r_hub, r) };
    t.frustum(a, b, ra, rb, d.seg(r_hub), (true, true));
    let (a, b) = span(len - disc, len);
    t.cylinder(a, b, rf, d.seg(rf));
    if d.fine {
        // Nuts on the back of the disc.
        let rb = (rf + r_hub) * 0.5;
        let (a, b) = span(len - disc - 18.0, len - disc);
        let base = t.xf;
        for k in 0..p.bolts {
            let a_k = TAU * (k as f32 + 0.5) / p.bolts as f32;
            t.xf =
                base * Affine3A::from_translation(Vec3::new(0.0, rb * a_k.cos(), rb * a_k.sin()));
            t.cylinder(a, b, 14.0 + r * 0.05, 6);
        }
        t.xf = base;
    }
}

fn valve(t: &mut Tess, d: &Detail, dn: u8) {
    let p = DNS[dn as usize];
    let (r, rf, len) = (p.od * 0.5, p.flange_od * 0.5, p.valve_len as f32);
    let disc = (p.flange_len as f32 * 0.4).max(14.0);
    let half = len * 0.5;
    t.material = Mat::Valve.id();
    t.cylinder(-half, -half + disc, rf, d.seg(rf));
    t.cylinder(half - disc, half, rf, d.seg(rf));
    t.cylinder(-half + disc, half - disc, r * 1.1, d.seg(r * 1.1));
    // Body and bonnet up +Z.
    let up = frame(Vec3::ZERO, Vec3::Z, Vec3::X);
    t.xf = up;
    // Within the face-to-face length, so the body stays clear of the pipes.
    let rb = (r * 1.25 + 10.0).min(half - disc - 2.0);
    t.cylinder(-r * 1.1, r * 1.4, rb, d.seg(rb));
    t.cylinder(r * 1.4, r * 1.4 + 30.0, rb * 1.15, d.seg(rb * 1.15));
    let bonnet_top = r * 1.4 + 30.0 + r * 1.6 + 60.0;
    t.frustum(
        r * 1.4 + 30.0,
        bonnet_top,
        rb * 0.8,
        rb * 0.5,
        d.seg(rb * 0.8),
        (true, true),
    );
    // Stem and handwheel.
    let stem_top = bonnet_top + r * 1.2 + 120.0;
    let rs = (r * 0.08).max(8.0);
    t.cylinder(bonnet_top, stem_top + 40.0, rs, d.seg(rs));
    let rw = (rf * 0.9).max(90.0);
    let tube = (rw * 0.06).max(8.0);
    t.xf = Affine3A::from_translation(Vec3::new(0.0, 0.0, stem_top));
    t.torus(rw, tube, TAU, d.seg(rw).max(12), d.seg(tube).min(10), false);
    if d.fine {
        for k in 0..3 {
            let a = TAU * k as f32 / 3.0;
            t.xf = along(
                Vec3::new(0.0, 0.0, stem_top),
                Vec3::new(a.cos(), a.sin(), 0.0),
            );
            t.cylinder(rs, rw - tube * 0.5, tube * 0.6, 6);
        }
    }
}

/// A nozzle of size `dn` leaving a shell at `at` along the unit `dir`: a stub
/// from `inset` inside the shell to `NOZZLE` past `at`, then a flange, blind
/// or open for a pipe.
fn nozzle(t: &mut Tess, d: &Detail, at: Vec3, dir: Vec3, inset: f32, dn: u8, blind: bool) {
    let p = DNS[dn as usize];
    let r = p.od * 0.5;
    let saved = (t.xf, t.material);
    t.xf = saved.0 * along(at, dir);
    t.cylinder(-inset, NOZZLE, r, d.seg(r));
    flange(t, d, dn, NOZZLE, 1.0);
    if blind {
        let disc = (p.flange_len as f32 * 0.4).max(14.0);
        let face = NOZZLE + p.flange_len as f32;
        t.cylinder(
            face,
            face + disc,
            p.flange_od * 0.5,
            d.seg(p.flange_od * 0.5),
        );
    }
    (t.xf, t.material) = saved;
}

fn vessel(t: &mut Tess, d: &Detail, dia: u32, h: u32, dn: u8, seed: u16) {
    let mut rng = crate::Rng::new(u64::from(seed) ^ (u64::from(dia) << 20) ^ (u64::from(h) << 40));
    let r = dia as f32 * 0.5;
    let (skirt, h) = (vessel_skirt(dia) as f32, h as f32);
    let seg = d.seg(r);
    t.material = Mat::Vessel.id();
    t.xf = frame(Vec3::ZERO, Vec3::Z, Vec3::X);
    t.cylinder(0.0, skirt, r, seg);
    t.frustum(skirt, skirt + h, r, r, seg, (false, false));
    t.xf = frame(Vec3::new(0.0, 0.0, skirt + h), Vec3::Z, Vec3::X);
    t.dish(r, r * 0.5, d.rings, seg);
    t.xf = frame(Vec3::new(0.0, 0.0, skirt), -Vec3::Z, Vec3::X);
    t.dish(r, r * 0.5, d.rings, seg);
    t.xf = Affine3A::IDENTITY;
    // The top nozzle, where a pipe connects, and blind side nozzles.
    nozzle(
        t,
        d,
        Vec3::new(0.0, 0.0, skirt + h + r * 0.5),
        Vec3::Z,
        20.0,
        dn,
        false,
    );
    let side = 2 + rng.below(3) as u32;
    for k in 0..side {
        let a = TAU * (k as f32 + rng.unit() as f32 * 0.6) / side as f32;
        let z = skirt + h * (0.15 + 0.7 * rng.unit() as f32);
        let dir = Vec3::new(a.cos(), a.sin(), 0.0);
        let size = rng.below(u64::from(dn) + 1) as u8;
        nozzle(
            t,
            d,
            Vec3::new(0.0, 0.0, z) + dir * r,
            dir,
            30.0,
            size,
            true,
        );
    }
    if h > 1500.0 {
        let a = TAU * rng.unit() as f32;
        let dir = Vec3::new(a.cos(), a.sin(), 0.0);
        nozzle(
            t,
            d,
            Vec3::new(0.0, 0.0, skirt + 600.0) + dir * r,
            dir,
            30.0,
            8,
            true,
        );
    }
}

fn drum(t: &mut Tess, d: &Detail, dia: u32, l: u32, dn: u8, seed: u16, exchanger: bool) {
    let mut rng = crate::Rng::new(u64::from(seed) ^ (u64::from(dia) << 20) ^ (u64::from(l) << 40));
    let r = dia as f32 * 0.5;
    let axis = drum_axis(dia) as f32;
    let half = l as f32 * 0.5;
    let seg = d.seg(r);
    t.material = Mat::Steel.id();
    for x in [-0.3 * l as f32, 0.3 * l as f32] {
        t.block(
            Vec3::new(x, 0.0, (axis - r * 0.4) * 0.5),
            Vec3::new(250.0, r * 1.6, axis - r * 0.4),
        );
    }
    t.material = Mat::Vessel.id();
    t.xf = Affine3A::from_translation(Vec3::new(0.0, 0.0, axis));
    if exchanger {
        // Shell, girth flanges, channel and bonnet at -X, dished rear head at +X.
        let ch = (0.18 * l as f32).max(400.0);
        t.frustum(-half + ch, half, r, r, seg, (false, false));
        let rf = r * 1.12 + 30.0;
        t.cylinder(-half + ch - 80.0, -half + ch, rf, d.seg(rf));
        t.cylinder(
            -half + ch - 80.0 - (ch - 160.0),
            -half + ch - 80.0,
            r * 1.03,
            d.seg(r),
        );
        t.cylinder(-half, -half + 80.0, rf, d.seg(rf));
        t.xf = frame(Vec3::new(-half, 0.0, axis), -Vec3::X, -Vec3::Y);
        t.dish(r, r * 0.35, d.rings, seg);
        t.xf = Affine3A::IDENTITY;
        let x = -half + ch * 0.5;
        nozzle(t, d, Vec3::new(x, 0.0, axis + r), Vec3::Z, 20.0, dn, true);
        nozzle(t, d, Vec3::new(x, 0.0, axis - r), -Vec3::Z, 20.0, dn, true);
    } else {
        t.frustum(-half, half, r, r, seg, (false, false));
        t.xf = frame(Vec3::new(-half, 0.0, axis), -Vec3::X, -Vec3::Y);
        t.dish(r, r * 0.5, d.rings, seg);
        t.xf = Affine3A::IDENTITY;
        let x = -0.3 * l as f32;
        nozzle(
            t,
            d,
            Vec3::new(x, 0.0, axis + r),
            Vec3::Z,
            20.0,
            rng.below(u64::from(dn) + 1) as u8,
            true,
        );
    }
    t.xf = frame(Vec3::new(half, 0.0, axis), Vec3::X, Vec3::Y);
    t.dish(r, r * 0.5, d.rings, seg);
    t.xf = Affine3A::IDENTITY;
    let (nx, _) = drum_nozzle(dia, l, dn);
    nozzle(
        t,
        d,
        Vec3::new(nx as f32, 0.0, axis + r),
        Vec3::Z,
        20.0,
        dn,
        false,
    );
    for _ in 0..1 + rng.below(2) {
        // Between the saddles, clear of them.
        let x = (rng.unit() as f32 - 0.5) * l as f32 * 0.3;
        let a = PI * (0.2 + 0.6 * rng.unit() as f32);
        let dir = Vec3::new(0.0, a.cos(), -a.sin());
        nozzle(
            t,
            d,
            Vec3::new(x, 0.0, axis) + dir * r,
            dir,
            30.0,
            rng.below(u64::from(dn) + 1) as u8,
            true,
        );
    }
}

fn pump(t: &mut Tess, d: &Detail, size: u8) {
    let (rc, axis) = pump_casing(size);
    let (x0, x1) = pump_extent(size);
    let (x0, x1) = (x0 as f32, x1 as f32);
    let dn = pump_dn(size);
    t.material = Mat::Steel.id();
    t.block(
        Vec3::new((x0 + x1) * 0.5, 0.0, 60.0),
        Vec3::new(x1 - x0, rc * 2.4, 120.0),
    );
    t.material = Mat::Pump.id();
    // Volute with its axis along X, pedestal, bearing frame.
    t.cylinder(-rc * 0.45, rc * 0.45, rc, d.seg(rc));
    t.block(
        Vec3::new(0.0, 0.0, (axis - rc * 0.5 + 120.0) * 0.5),
        Vec3::new(rc * 1.2, rc * 1.0, axis - rc * 0.5 - 120.0),
    );
    t.xf = Affine3A::from_translation(Vec3::new(0.0, 0.0, axis));
    t.cylinder(-rc * 0.45, rc * 0.45, rc, d.seg(rc));
    let rbr = rc * 0.45;
    t.frustum(
        rc * 0.45,
        rc * 0.45 + 420.0,
        rc * 0.6,
        rbr,
        d.seg(rbr),
        (true, true),
    );
    t.xf = Affine3A::IDENTITY;
    // Suction along -X, discharge up.
    nozzle(
        t,
        d,
        Vec3::new(-rc * 0.45, 0.0, axis),
        -Vec3::X,
        20.0,
        dn + 1,
        false,
    );
    nozzle(
        t,
        d,
        Vec3::new(0.0, 0.0, axis + rc),
        Vec3::Z,
        20.0,
        dn,
        false,
    );
    // Coupling guard, motor with fan cowl, terminal box.
    let xm = rc * 0.45 + 420.0;
    t.material = Mat::Safety.id();
    t.block(
        Vec3::new(xm + 130.0, 0.0, axis),
        Vec3::new(260.0, rbr * 2.2, rbr * 2.2),
    );
    t.material = Mat::Motor.id();
    let rm = rc * 0.95;
    let motor_end = x1 - 120.0;
    t.block(
        Vec3::new(
            (xm + 260.0 + motor_end) * 0.5,
            0.0,
            (axis - rm + 120.0) * 0.5 + 60.0,
        ),
        Vec3::new(motor_end - xm - 300.0, rm * 1.6, axis - rm - 120.0),
    );
    t.xf = Affine3A::from_translation(Vec3::new(0.0, 0.0, axis));
    t.cylinder(xm + 260.0, motor_end - 160.0, rm, d.seg(rm));
    t.frustum(
        motor_end - 160.0,
        motor_end,
        rm * 0.97,
        rm * 0.75,
        d.seg(rm),
        (true, true),
    );
    t.xf = Affine3A::IDENTITY;
    t.block(
        Vec3::new((xm + motor_end) * 0.5, 0.0, axis + rm + 80.0),
        Vec3::new(260.0, 220.0, 160.0),
    );
}

fn cabinet(t: &mut Tess, w: u32) {
    let w = w as f32;
    t.material = Mat::Steel.id();
    t.block(Vec3::new(0.0, 0.0, 50.0), Vec3::new(w, 600.0, 100.0));
    t.material = Mat::Cabinet.id();
    t.block(Vec3::new(0.0, 0.0, 1150.0), Vec3::new(w, 600.0, 2100.0));
    let doors = (w / 800.0).round().max(1.0) as u32;
    let pitch = w / doors as f32;
    t.material = Mat::Steel.id();
    for k in 0..doors {
        let x = -w * 0.5 + pitch * (k as f32 + 0.5);
        t.block(
            Vec3::new(x + pitch * 0.35, -310.0, 1100.0),
            Vec3::new(20.0, 20.0, 200.0),
        );
        t.block(
            Vec3::new(x, -305.0, 1900.0),
            Vec3::new(pitch * 0.6, 10.0, 160.0),
        );
    }
}

fn hvac(t: &mut Tess, d: &Detail, l: u32) {
    let l = l as f32;
    t.material = Mat::Steel.id();
    t.block(
        Vec3::new(0.0, 0.0, 100.0),
        Vec3::new(l + 200.0, 2200.0, 200.0),
    );
    t.material = Mat::Hvac.id();
    t.block(Vec3::new(0.0, 0.0, 950.0), Vec3::new(l, 2000.0, 1500.0));
    let fans = (l / 1600.0).floor().max(1.0) as u32;
    let pitch = l / fans as f32;
    for k in 0..fans {
        let x = -l * 0.5 + pitch * (k as f32 + 0.5);
        t.xf = frame(Vec3::new(x, 0.0, 1700.0), Vec3::Z, Vec3::X);
        t.frustum(0.0, 350.0, 640.0, 620.0, d.seg(640.0), (true, true));
        t.cylinder(350.0, 420.0, 160.0, d.seg(160.0));
    }
}

fn ladder(t: &mut Tess, d: &Detail, h: u32) {
    let h = h as f32;
    t.material = Mat::Safety.id();
    for y in [-225.0, 225.0] {
        t.block(Vec3::new(0.0, y, h * 0.5), Vec3::new(60.0, 12.0, h));
    }
    let rungs = ((h - 150.0) / 300.0).floor() as u32;
    t.xf = frame(Vec3::ZERO, Vec3::Y, -Vec3::X);
    for k in 0..rungs {
        t.xf.translation = Vec3::new(0.0, 0.0, 300.0 * (k + 1) as f32).into();
        t.cylinder(-219.0, 219.0, 10.0, d.seg(10.0));
    }
    if d.fine && h > 2600.0 {
        // Hoops open towards the ladder and five flat bars.
        let (rc, c) = (360.0, Vec3::new(390.0, 0.0, 0.0));
        let open = 0.45f32;
        let mut z = 2300.0;
        while z < h - 50.0 {
            t.xf =
                Affine3A::from_translation(c + Vec3::Z * z) * Affine3A::from_rotation_z(-PI + open);
            t.torus(rc, 8.0, TAU - 2.0 * open, d.seg(rc), 6, true);
            z += 900.0;
        }
        t.xf = Affine3A::IDENTITY;
        for k in 0..5 {
            let a = -PI + open + (TAU - 2.0 * open) * (k as f32 + 0.5) / 5.0;
            let p = c + Vec3::new(a.cos(), a.sin(), 0.0) * (rc + 14.0);
            t.block(
                Vec3::new(p.x, p.y, (2300.0 + h) * 0.5),
                Vec3::new(10.0, 10.0, h - 2300.0),
            );
        }
    }
}

fn handrail(t: &mut Tess, d: &Detail, len: u32) {
    let len = len as f32;
    t.material = Mat::Safety.id();
    let posts = (len / 1800.0).ceil() as u32 + 1;
    let pitch = (len - 60.0) / (posts - 1) as f32;
    t.xf = frame(Vec3::ZERO, Vec3::Z, Vec3::X);
    for k in 0..posts {
        t.xf.translation = Vec3::new(-len * 0.5 + 30.0 + pitch * k as f32, 0.0, 0.0).into();
        t.cylinder(0.0, 1070.0, 21.0, d.seg(21.0));
    }
    t.xf = Affine3A::IDENTITY;
    let (a, b) = (-len * 0.5, len * 0.5);
    t.xf.translation = Vec3::new(0.0, 0.0, 1100.0).into();
    t.cylinder(a, b, 24.0, d.seg(24.0));
    t.xf.translation = Vec3::new(0.0, 0.0, 550.0).into();
    t.cylinder(a + 10.0, b - 10.0, 17.0, d.seg(17.0));
    t.xf = Affine3A::IDENTITY;
    t.block(
        Vec3::new(0.0, 30.0, 50.0),
        Vec3::new(len - 80.0, 8.0, 100.0),
    );
}

fn tray(t: &mut Tess, d: &Detail, len: u32, w: u32) {
    let (len, w) = (len as f32, w as f32);
    let half = len * 0.5;
    t.material = Mat::Tray.id();
    let (outline, cap) = c_section(100.0, 25.0, 3.0);
    // Left rail with its flanges pointing inwards (+y), right rail mirrored by a turn.
    t.xf = Affine3A::from_translation(Vec3::new(0.0, -w * 0.5, 0.0));
    t.extrude(&outline, &cap, -half, half);
    t.xf = Affine3A::from_translation(Vec3::new(0.0, w * 0.5, 0.0))
        * Affine3A::from_rotation_x(0.0)
        * Affine3A::from_mat3(Mat3::from_cols(-Vec3::X, -Vec3::Y, Vec3::Z));
    t.extrude(&outline, &cap, -half, half);
    t.xf = Affine3A::IDENTITY;
    let pitch = if d.fine { 300.0 } else { 600.0 };
    let rungs = ((len - 100.0) / pitch).floor() as u32;
    let first = -(rungs as f32 - 1.0) * pitch * 0.5;
    for k in 0..rungs {
        t.block(
            Vec3::new(first + pitch * k as f32, 0.0, 10.0),
            Vec3::new(40.0, w - 8.0, 20.0),
        );
    }
    // The cables.
    t.material = Mat::Cabinet.id();
    t.block(
        Vec3::new(0.0, 0.0, 50.0),
        Vec3::new(len - 10.0, w - 60.0, 60.0),
    );
}

fn tank(t: &mut Tess, d: &Detail, dia: u32, h: u32) {
    let r = dia as f32 * 0.5;
    let h = h as f32;
    let seg = d.seg(r).min(4 * d.seg);
    t.material = Mat::Tank.id();
    t.xf = frame(Vec3::ZERO, Vec3::Z, Vec3::X);
    t.cylinder(0.0, 12.0, r + 60.0, seg);
    t.frustum(12.0, h, r, r, seg, (false, false));
    t.frustum(h, h + r * 0.2, r + 40.0, 0.0, seg, (true, false));
    // Wind girder.
    t.cylinder(h - 700.0, h - 690.0, r + 250.0, seg);
    t.xf = Affine3A::IDENTITY;
    nozzle(t, d, Vec3::new(0.0, -r, 600.0), -Vec3::Y, 30.0, 5, false);
    nozzle(t, d, Vec3::new(r, 0.0, 600.0), Vec3::X, 30.0, 4, true);
    nozzle(
        t,
        d,
        Vec3::new(-r * FRAC_1_SQRT_2, -r * FRAC_1_SQRT_2, 900.0),
        Vec3::new(-FRAC_1_SQRT_2, -FRAC_1_SQRT_2, 0.0),
        30.0,
        8,
        true,
    );
    let top = h + r * 0.2 * 0.5;
    nozzle(
        t,
        d,
        Vec3::new(r * 0.5, 0.0, top - 100.0),
        Vec3::Z,
        60.0,
        3,
        true,
    );
}
