//! `dmu collide --bcf`: the clashes of a run as BCF issues, one topic per pair
//! of parts per record, each with a camera framing the pair, the two parts
//! selected and a snapshot rendered offscreen.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use anyhow::Context as _;
use dmu_app::bcf::{self, Component, Topic, Viewpoint};
use dmu_app::units::LengthUnit;
use dmu_collide::{Finding, Step};
use dmu_geom::Aabb3d;
use dmu_render::{Camera, Capture, Culling, Renderer, RendererOptions, View, headless_device};
use dmu_scene::{PartId, Scene};
use dmu_tree::{Tree, TreeOptions};
use glam::{DAffine3, DVec3};

/// The snapshot's vertical field of view, degrees (the viewer's default).
const FOV_Y_DEG: f64 = 60.0;

/// One pair of parts that clashes in a record, as first found.
#[derive(Clone, Debug)]
pub struct PairClash {
    /// The first finding of the pair (the moved part first).
    pub a_id: u32,
    /// The other part.
    pub b_id: u32,
    /// `hard`, `contact`, `soft` or `impact`, at the first step.
    pub kind: &'static str,
    /// The first step with a finding for the pair, and its time.
    pub step: usize,
    /// See `step`.
    pub t: f64,
    /// The first finding's distance (0 when hard) and time of impact.
    pub distance: f64,
    /// See `distance`.
    pub toi: Option<f64>,
    /// Where, world units.
    pub point: [f64; 3],
    /// Steps with a finding for the pair, and the last of them with its time.
    pub steps: usize,
    /// See `steps`.
    pub last_step: usize,
    /// See `steps`.
    pub last_t: f64,
}

/// The pairs clashing in one record's findings (in step order), each once, at
/// the first step where it appears, in the order they first appear: a record
/// of 3,000 steps of the same contact is one issue, not 3,000.
pub fn first_clashes(findings: &[Finding<'_>]) -> Vec<PairClash> {
    let mut pairs: Vec<PairClash> = Vec::new();
    let mut index: HashMap<(u32, u32), usize> = HashMap::new();
    for f in findings {
        let key = (f.a_id.min(f.b_id), f.a_id.max(f.b_id));
        match index.get(&key) {
            Some(&i) => {
                let p = &mut pairs[i];
                if p.last_step != f.step {
                    p.steps += 1;
                    p.last_step = f.step;
                    p.last_t = f.t;
                }
            }
            None => {
                index.insert(key, pairs.len());
                pairs.push(PairClash {
                    a_id: f.a_id,
                    b_id: f.b_id,
                    kind: f.kind.as_str(),
                    step: f.step,
                    t: f.t,
                    distance: f.distance,
                    toi: f.toi,
                    point: f.point,
                    steps: 1,
                    last_step: f.step,
                    last_t: f.t,
                });
            }
        }
    }
    pairs
}

/// What `--bcf` asked for.
#[derive(Debug)]
pub struct BcfRequest<'a> {
    /// The archive to write.
    pub path: &'a Path,
    /// The model's unit (BCF is in metres).
    pub unit: LengthUnit,
    /// Snapshot size in pixels; none for no snapshots.
    pub snapshot: Option<(u32, u32)>,
    /// The clearance of the run, for the descriptions.
    pub clearance: f64,
}

/// What was written.
#[derive(Debug)]
pub struct BcfWritten {
    /// Topics in the archive.
    pub topics: usize,
    /// Topics with a snapshot.
    pub snapshots: usize,
}

/// The offscreen renderer of the snapshots.
struct Snapshots {
    device: dmu_render::wgpu::Device,
    queue: dmu_render::wgpu::Queue,
    renderer: Renderer,
    capture: Capture,
    size: (u32, u32),
}

impl Snapshots {
    fn open(scene: &Scene, tree: &Tree, size: (u32, u32)) -> anyhow::Result<Self> {
        let (device, queue, _) = headless_device()?;
        let renderer = Renderer::new(&device, &queue, scene, tree, RendererOptions::default());
        let capture = Capture::new(&device, size);
        Ok(Self {
            device,
            queue,
            renderer,
            capture,
            size,
        })
    }

    /// The view from `camera` as PNG bytes, `parts` tinted as clashing.
    fn take(
        &mut self,
        scene: &Scene,
        tree: &Tree,
        camera: Camera,
        parts: [PartId; 2],
    ) -> anyhow::Result<Vec<u8>> {
        for p in parts {
            self.renderer.set_clashing(p, true);
        }
        let mut view = View::new(camera, self.size, Culling::Frustum);
        let drawn = self
            .renderer
            .render(&mut view, scene, tree, scene, self.capture.frame_target())
            .map(|_| ());
        for p in parts {
            self.renderer.set_clashing(p, false);
        }
        drawn?;
        let image = self.capture.read_color(&self.device, &self.queue)?;
        Ok(dmu_render::encode_png(&image)?)
    }
}

/// The camera of a clash: looking from the +X, −Y, +Z side (the viewer's iso
/// view) at `bounds` (both parts' boxes; for an impact, the part hit and the
/// point of impact), framed as the viewer frames a selection.
fn clash_camera(tree: &Tree, bounds: &Aabb3d) -> Camera {
    let forward = DVec3::new(-1.0, 1.0, -1.0);
    let framed = |near| Camera::framing(bounds, forward, DVec3::Z, FOV_Y_DEG.to_radians(), near);
    let first = framed(bounds.extent().length().max(1e-3) * 1e-4);
    framed(crate::cmd_render::default_near(tree, first.eye))
}

/// Writes the BCF archive of a run: for each record in order, a topic per
/// pair in `clashes[record]`, with the parts at the poses of that pair's first
/// step (the records with clashes read again with `read`). `scene` is a copy of the model at its own poses (the run's workers
/// consumed theirs). Without a GPU adapter the snapshots are left out, with a
/// warning.
pub fn write_bcf(
    mut scene: Scene,
    read: impl Fn(usize, &Scene) -> anyhow::Result<Vec<Step>>,
    files: &[PathBuf],
    clashes: &[Vec<PairClash>],
    batch: bool,
    request: &BcfRequest<'_>,
) -> anyhow::Result<BcfWritten> {
    let mut tree = Tree::build(&scene, TreeOptions::default());
    let mut snapshots = match request.snapshot {
        Some(size) if clashes.iter().any(|c| !c.is_empty()) => {
            match Snapshots::open(&scene, &tree, size) {
                Ok(s) => Some(s),
                Err(e) => {
                    eprintln!("dmu: warning: {e:#}: the BCF file is written without snapshots");
                    None
                }
            }
        }
        _ => None,
    };
    let model_poses: Vec<DAffine3> = scene.part_ids().map(|p| scene.part_world(p)).collect();
    let mut topics = Vec::new();
    let mut with_snapshot = 0;
    for (index, (file, pairs)) in files.iter().zip(clashes).enumerate() {
        if pairs.is_empty() {
            continue;
        }
        // The scene is at the model's poses between records.
        let steps = read(index, &scene)?;
        let record = file.display().to_string();
        let record_name = file
            .file_name()
            .map_or_else(|| record.clone(), |n| n.to_string_lossy().into_owned());
        // The pairs come in order of first step: the steps are replayed
        // forward once.
        let mut next_step = 0;
        let mut moved = Vec::new();
        for pair in pairs {
            debug_assert!(pair.step + 1 >= next_step, "pairs in step order");
            for step in &steps[next_step..=pair.step] {
                for m in &step.moves {
                    tree.move_part(&mut scene, m.part, m.world);
                    moved.push(m.part);
                }
            }
            next_step = pair.step + 1;
            let (a, b) = (PartId(pair.a_id), PartId(pair.b_id));
            // An impact happened along the move, not where the moved part
            // ends: frame the part hit and the point of impact.
            let bounds = match pair.toi {
                Some(_) => scene
                    .part_world_bounds(b)
                    .grown(DVec3::from_array(pair.point)),
                None => scene.part_world_bounds(a).union(scene.part_world_bounds(b)),
            };
            let camera = clash_camera(&tree, &bounds);
            let snapshot = match snapshots.as_mut() {
                Some(s) => Some(s.take(&scene, &tree, camera, [a, b]).with_context(|| {
                    format!("rendering the snapshot of {record} step {}", pair.step)
                })?),
                None => None,
            };
            with_snapshot += usize::from(snapshot.is_some());
            topics.push(topic(
                &scene,
                pair,
                &record,
                batch.then_some(&*record_name),
                camera,
                snapshot,
                request.clearance,
            ));
        }
        moved.sort_unstable();
        moved.dedup();
        for part in moved {
            tree.move_part(&mut scene, part, model_poses[part.index()]);
        }
    }
    let project = format!("dmu collide: {}", files.len());
    bcf::write_bcfzip(
        request.path,
        &topics,
        Some(&project),
        request.unit.per_metre(),
    )?;
    Ok(BcfWritten {
        topics: topics.len(),
        snapshots: with_snapshot,
    })
}

/// The topic of one clashing pair.
fn topic(
    scene: &Scene,
    pair: &PairClash,
    record: &str,
    record_name: Option<&str>,
    camera: Camera,
    snapshot: Option<Vec<u8>>,
    clearance: f64,
) -> Topic {
    let (a, b) = (
        scene.part_name(PartId(pair.a_id)),
        scene.part_name(PartId(pair.b_id)),
    );
    let prefix = record_name.map_or_else(String::new, |r| format!("{r}: "));
    let title = format!(
        "{prefix}{}: {a} × {b} at step {} (t={})",
        pair.kind, pair.step, pair.t
    );
    let measure = match pair.toi {
        Some(toi) => format!("impact at {toi:.6} of the move"),
        None => format!("distance {:.6}", pair.distance),
    };
    let p = pair.point;
    let description = format!(
        "{} between {a} (#{}) and {b} (#{}) at step {} (t={}) of record {record}: {measure}, at [{:.3}, {:.3}, {:.3}] (model units). \
         The pair has findings at {} step{}, the last at step {} (t={}). Found by dmu collide with clearance {clearance}.",
        pair.kind,
        pair.a_id,
        pair.b_id,
        pair.step,
        pair.t,
        p[0],
        p[1],
        p[2],
        pair.steps,
        if pair.steps == 1 { "" } else { "s" },
        pair.last_step,
        pair.last_t
    );
    Topic {
        description,
        topic_type: "Clash".to_owned(),
        labels: vec![pair.kind.to_owned(), "dmu collide".to_owned()],
        viewpoints: vec![Viewpoint {
            camera: Some(bcf::Camera::perspective(&camera)),
            selected: vec![Component::part(a), Component::part(b)],
            snapshot: snapshot.map(Into::into),
            ..Viewpoint::new()
        }],
        ..Topic::new(title, "dmu collide")
    }
}
