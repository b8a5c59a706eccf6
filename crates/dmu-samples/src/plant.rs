//! `plant`: a procedural process plant of any size, the default model of dmu.
//!
//! The site is a grid of plots. Each plot holds a process building (a steel
//! frame of several storeys with floors, cladding, equipment, piping, cable
//! trays, ladders) or, now and then, a tank farm, and in front of it a section of
//! the pipe rack that runs along the plot row. Floors and cladding hide most of
//! a building's contents from most viewpoints, as in real plants.
//!
//! Design choices:
//! - Parts come from a catalogue of specs in integer millimetres (a flange of a
//!   given size, a pipe of a given length, a beam of a given span), so equal
//!   parts share one mesh as standard parts do in CAD; equipment is sized per
//!   piece and so mostly unique.
//! - The size is set by a triangle budget: units are planned whole, then their
//!   parts are added in order (storey by storey) while they fit, so the scene
//!   lands just under the target. Tessellation gets finer with the target, and
//!   the part count grows with it too.
//! - Past a budget of unique triangles, plots re-use earlier unit plans whole
//!   (more instances of the same meshes), so memory stays bounded at hundreds of
//!   millions of triangles.
//! - Meshes are chunked in parallel with rayon; everything else is sequential
//!   and driven by one seeded [`Rng`], so a seed always gives the same plant.
//!
//! Conventions: millimetres, Z up, X along the plot rows. Every part's geometry
//! is local (f32, within metres of its own origin); its world transform (f64)
//! carries the site position and [`PlantOptions::origin`].
//! The assembly tree is `plant / unit / area / system / part`, with names like
//! `U03-L2-PIPE-0147` (unit 3, storey 2, piping, part 147).

mod building;
mod catalog;
mod rack;
mod tank_farm;
mod unit;

use std::collections::HashMap;

use glam::{DAffine3, DVec3};
use rayon::prelude::*;

use crate::Rng;
use catalog::{Detail, MATERIALS, Spec};
use dmu_scene::{DEFAULT_CHUNK_TRIANGLES, Scene, SceneBuilder};
use dmu_scene::{MeshData, chunk_mesh};
use dmu_scene::{MeshId, NodeId};
use unit::{System, UnitPlan};

/// Options of [`plant`].
#[derive(Clone, Debug)]
pub struct PlantOptions {
    /// Triangle target, instances counted. The plant lands just under it (within
    /// a fraction of a percent from 10 000 triangles up).
    pub triangles: u64,
    /// Random seed: the same options always give the same plant.
    pub seed: u64,
    /// World position of the site's corner, millimetres. Real plant coordinates
    /// are far from zero; parts keep local f32 geometry and f64 transforms.
    pub origin: DVec3,
    /// Maximum triangles per chunk.
    pub chunk_triangles: u32,
    /// Triangles of distinct meshes after which plots re-use earlier unit
    /// plans whole, so geometry stays bounded as instances grow (24M by
    /// default).
    pub unique_triangles: u64,
}

impl Default for PlantOptions {
    /// One million triangles, seed 1, at a UTM-like position (millimetres),
    /// default chunks.
    fn default() -> Self {
        Self {
            triangles: 1_000_000,
            seed: 1,
            origin: DVec3::new(4_512_000.0, 5_341_000.0, 12_000.0),
            chunk_triangles: DEFAULT_CHUNK_TRIANGLES,
            unique_triangles: 24_000_000,
        }
    }
}

/// Plot size: one building (or tank farm) and its rack section.
const PLOT: f64 = 48_000.0;
/// Triangles per batch of meshes chunked in parallel (bounds the transient copy).
const CHUNK_BATCH: u64 = 2_000_000;

/// How big each unit is, chosen from the target so small plants are complete.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Scale {
    Tiny,
    Small,
    Full,
}

/// Generates the plant.
pub fn plant(options: &PlantOptions) -> Scene {
    let mut generator = Generator::new(options);
    generator.run(options);
    generator.finish()
}

/// Tessellation detail for a target: segments round a 100 mm pipe grow as the
/// fourth root of the target, 8 at 10k, 28 at 1M, 48 at 10M, 64 from 100M on.
fn detail(target: u64) -> Detail {
    let seg = (8.0 * (target.max(1) as f64 / 1e4).powf(0.25)).round() as u32;
    let seg = seg.clamp(8, 64).div_ceil(4) * 4;
    Detail {
        seg,
        steps: (seg / 4).max(2),
        rings: (seg / 4).max(2),
        fine: seg >= 16,
    }
}

fn scale(target: u64) -> Scale {
    match target {
        0..60_000 => Scale::Tiny,
        60_000..600_000 => Scale::Small,
        _ => Scale::Full,
    }
}

/// Unit plans kept for replication, by kind.
#[derive(Default)]
struct Variants {
    buildings: Vec<UnitPlan>,
    farms: Vec<UnitPlan>,
    racks: Vec<UnitPlan>,
}

struct Generator {
    builder: SceneBuilder,
    detail: Detail,
    target: u64,
    /// Triangles of the parts added so far (instances counted).
    total: u64,
    catalog: HashMap<Spec, u32>,
    meshes: Vec<MeshData>,
    mesh_triangles: Vec<u64>,
    mesh_used: Vec<bool>,
    /// Triangles of all meshes built so far.
    unique: u64,
    /// Parts to add once their meshes are: (node, catalogue index).
    parts: Vec<(NodeId, u32)>,
    units: u32,
}

impl Generator {
    fn new(options: &PlantOptions) -> Self {
        let mut builder = SceneBuilder::new("plant", options.chunk_triangles);
        for (name, color) in MATERIALS {
            builder.add_material(name, color);
        }
        Self {
            builder,
            detail: detail(options.triangles),
            target: options.triangles,
            total: 0,
            catalog: HashMap::new(),
            meshes: Vec::new(),
            mesh_triangles: Vec::new(),
            mesh_used: Vec::new(),
            unique: 0,
            parts: Vec::new(),
            units: 0,
        }
    }

    /// True when the target is met to 0.001% (parts are added only while they
    /// fit, so the total never exceeds it).
    fn done(&self) -> bool {
        self.target - self.total <= self.target / 100_000
    }

    fn run(&mut self, options: &PlantOptions) {
        let scale = scale(self.target);
        let mut variants = Variants::default();
        let mut rack_of_row: Vec<usize> = Vec::new();
        let mut columns = 1u64;
        let mut plot = 0u64;
        while !self.done() {
            let (col, row) = (plot % columns, plot / columns);
            let corner = options.origin + DVec3::new(col as f64 * PLOT, row as f64 * PLOT, 0.0);
            let mut rng = Rng::new(options.seed ^ (plot + 1).wrapping_mul(0x9e37_79b9_7f4a_7c15));
            let replicate = self.unique >= options.unique_triangles;
            let farm = self.target >= 3_000_000 && plot % 6 == 4;
            let before = self.total;

            let list = if farm {
                &mut variants.farms
            } else {
                &mut variants.buildings
            };
            let main = if replicate && !list.is_empty() {
                rng.below(list.len() as u64) as usize
            } else if farm {
                list.push(tank_farm::tank_farm(&mut rng, PLOT));
                list.len() - 1
            } else {
                list.push(building::building(&mut rng, scale, PLOT));
                list.len() - 1
            };
            let plan = if farm {
                &variants.farms[main]
            } else {
                &variants.buildings[main]
            };
            self.emit(plan, corner);

            if !self.done() {
                // One rack design per row, so that its pipes and trays run through.
                if rack_of_row.len() as u64 <= row {
                    let index = if replicate && !variants.racks.is_empty() {
                        rng.below(variants.racks.len() as u64) as usize
                    } else {
                        let mut row_rng =
                            Rng::new(options.seed ^ (row + 1).wrapping_mul(0xd1b5_4a32_d192_ed03));
                        variants.racks.push(rack::rack(&mut row_rng, scale, PLOT));
                        variants.racks.len() - 1
                    };
                    rack_of_row.push(index);
                }
                self.emit(&variants.racks[rack_of_row[row as usize]], corner);
            }
            if self.total == before {
                // Nothing fits any more.
                break;
            }
            if plot == 0 {
                // Lay the plots out in a square-ish site, sized by the first plot.
                let plots = self.target.div_ceil(self.total.max(1));
                columns = (plots as f64).sqrt().ceil().max(1.0) as u64;
            }
            plot += 1;
        }
    }

    /// The catalogue index of a spec's mesh, tessellated on first use.
    fn mesh(&mut self, spec: &Spec) -> u32 {
        if let Some(&index) = self.catalog.get(spec) {
            return index;
        }
        let mesh = catalog::build(spec, &self.detail);
        let index = u32::try_from(self.meshes.len()).expect("catalogue over 4G meshes");
        let triangles = u64::from(mesh.triangle_count());
        self.unique += triangles;
        self.mesh_triangles.push(triangles);
        self.meshes.push(mesh);
        self.mesh_used.push(false);
        self.catalog.insert(*spec, index);
        index
    }

    /// Adds a unit's parts, in plan order, while they fit the target; creates
    /// the unit, area and system nodes on first use.
    fn emit(&mut self, plan: &UnitPlan, corner: DVec3) {
        let name = format!("U{:02}", self.units + 1);
        let unit_world = DAffine3::from_translation(corner + plan.anchor);
        let mut unit_node = None;
        let mut area_nodes: Vec<Option<NodeId>> = vec![None; plan.areas.len()];
        let mut systems: HashMap<(u16, System), (NodeId, u32)> = HashMap::new();
        for part in &plan.parts {
            let mesh = self.mesh(&part.spec);
            let triangles = self.mesh_triangles[mesh as usize];
            if self.total + triangles > self.target {
                continue;
            }
            let builder = &mut self.builder;
            let unit = *unit_node.get_or_insert_with(|| {
                builder.add_node(SceneBuilder::ROOT, name.clone(), unit_world)
            });
            let (area_name, z) = &plan.areas[part.area as usize];
            let area = *area_nodes[part.area as usize].get_or_insert_with(|| {
                let world = unit_world * DAffine3::from_translation(DVec3::new(0.0, 0.0, *z));
                builder.add_node(unit, format!("{name}-{area_name}"), world)
            });
            let (system, count) = systems.entry((part.area, part.system)).or_insert_with(|| {
                let world = builder.node_world(area);
                let node = builder.add_node(
                    area,
                    format!("{name}-{area_name}-{}", part.system.code()),
                    world,
                );
                (node, 0)
            });
            *count += 1;
            let node_name = format!("{name}-{area_name}-{}-{:04}", part.system.code(), count);
            let node = builder.add_node(*system, node_name, unit_world * part.at);
            self.parts.push((node, mesh));
            self.mesh_used[mesh as usize] = true;
            self.total += triangles;
        }
        if unit_node.is_some() {
            self.units += 1;
        }
    }

    /// Chunks the meshes in use (in parallel, a batch at a time), then adds the
    /// parts.
    fn finish(self) -> Scene {
        let Self {
            mut builder,
            meshes,
            mesh_used,
            mesh_triangles,
            parts,
            ..
        } = self;
        let chunk_triangles = builder.chunk_triangles();
        let mut ids = vec![MeshId(u32::MAX); meshes.len()];
        let mut batch: Vec<MeshData> = Vec::new();
        let mut batch_triangles = 0;
        let mut next = 0usize;
        let flush = |batch: &mut Vec<MeshData>, builder: &mut SceneBuilder| {
            let chunked: Vec<_> = std::mem::take(batch)
                .into_par_iter()
                .map(|m| chunk_mesh(&m, chunk_triangles))
                .collect();
            for mesh in chunked {
                builder.add_chunked_mesh(mesh);
            }
        };
        for (index, mesh) in meshes.into_iter().enumerate() {
            if !mesh_used[index] {
                continue;
            }
            ids[index] = MeshId::from_index(next);
            next += 1;
            batch_triangles += mesh_triangles[index];
            batch.push(mesh);
            if batch_triangles >= CHUNK_BATCH {
                flush(&mut batch, &mut builder);
                batch_triangles = 0;
            }
        }
        flush(&mut batch, &mut builder);
        for (node, mesh) in parts {
            builder.add_part(node, ids[mesh as usize]);
        }
        builder.finish()
    }
}
