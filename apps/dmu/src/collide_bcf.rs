//! `dmu collide --bcf`: the clashes of a run as BCF issues, one topic per pair
//! of parts per record, each with a camera framing the pair, the two parts
//! selected and a snapshot rendered offscreen.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use anyhow::Context as _;
use dmu_app::bcf::{self, ClashIssue, Component, Topic, Viewpoint};
use dmu_app::units::LengthUnit;
use dmu_collide::{Finding, FindingKind, Step};
use dmu_render::{Camera, Capture, Culling, Renderer, RendererOptions, View, headless_device};
use dmu_scene::{PartId, Scene};
use dmu_tree::{Tree, TreeOptions};
use glam::{DAffine3, DVec3};

/// One kind of finding of a pair in a record: its first finding and the
/// steps it was seen at.
#[derive(Clone, Debug)]
pub struct KindSeen {
    /// `hard`, `impact`, `contact` or `soft`.
    pub kind: FindingKind,
    /// That finding's moved part (an impact's mover) and the other: either
    /// part of a pair may be the one moved at a given step.
    pub a_id: u32,
    /// See `a_id`.
    pub b_id: u32,
    /// The first step with a finding of this kind, and its time.
    pub step: usize,
    /// See `step`.
    pub t: f64,
    /// That finding's distance (0 when hard) and time of impact.
    pub distance: f64,
    /// See `distance`.
    pub toi: Option<f64>,
    /// Where, world units.
    pub point: [f64; 3],
    /// Steps with a finding of this kind.
    pub steps: usize,
    /// The last of them.
    pub last_step: usize,
}

/// One pair of parts that clashes in a record: each kind it showed, worst
/// first, and the steps with any finding.
#[derive(Clone, Debug)]
pub struct PairClash {
    /// The kinds seen, worst first (never empty): the topic is titled with
    /// the first.
    pub kinds: Vec<KindSeen>,
    /// Steps with a finding for the pair, and the last of them with its time.
    pub steps: usize,
    /// See `steps`.
    pub last_step: usize,
    /// See `steps`.
    pub last_t: f64,
}

impl PairClash {
    /// The pair's worst finding.
    pub fn worst(&self) -> &KindSeen {
        &self.kinds[0]
    }
}

/// The pairs clashing in one record's findings (in step order), each once,
/// with its worst finding first, in the order of the steps of their worst
/// findings: a record of 3,000 steps of the same contact is one issue, not
/// 3,000, and a pair that goes from a soft clash to a hard one is one issue
/// about the hard clash.
pub fn pair_clashes(findings: &[Finding<'_>]) -> Vec<PairClash> {
    let mut pairs: Vec<PairClash> = Vec::new();
    let mut index: HashMap<(u32, u32), usize> = HashMap::new();
    for f in findings {
        let key = (f.a_id.min(f.b_id), f.a_id.max(f.b_id));
        let p = match index.get(&key) {
            Some(&i) => &mut pairs[i],
            None => {
                index.insert(key, pairs.len());
                pairs.push(PairClash {
                    kinds: Vec::new(),
                    steps: 0,
                    last_step: f.step,
                    last_t: f.t,
                });
                pairs.last_mut().expect("just pushed")
            }
        };
        if p.steps == 0 || p.last_step != f.step {
            p.steps += 1;
            p.last_step = f.step;
            p.last_t = f.t;
        }
        match p.kinds.iter_mut().find(|k| k.kind == f.kind) {
            Some(k) if k.last_step != f.step => {
                k.steps += 1;
                k.last_step = f.step;
            }
            Some(_) => {}
            None => p.kinds.push(KindSeen {
                kind: f.kind,
                a_id: f.a_id,
                b_id: f.b_id,
                step: f.step,
                t: f.t,
                distance: f.distance,
                toi: f.toi,
                point: f.point,
                steps: 1,
                last_step: f.step,
            }),
        }
    }
    for p in &mut pairs {
        p.kinds.sort_by_key(|k| k.kind);
    }
    // The topics are written replaying the record forward once.
    pairs.sort_by_key(|p| p.worst().step);
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

/// Writes the BCF archive of a run: for each record in order, a topic per
/// pair in `clashes[record]`, with the parts at the poses of the step of that
/// pair's worst finding (the records with clashes read again with `read`).
/// `scene` is a copy of the model at its own poses (the run's workers
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
        // The pairs come in the order of their worst findings' steps: the
        // steps are replayed forward once.
        let mut next_step = 0;
        let mut moved = Vec::new();
        for pair in pairs {
            debug_assert!(pair.worst().step + 1 >= next_step, "pairs in step order");
            let worst = pair.worst();
            for step in &steps[next_step..=worst.step] {
                for m in &step.moves {
                    tree.move_part(&mut scene, m.part, m.world);
                    moved.push(m.part);
                }
            }
            next_step = worst.step + 1;
            let (a, b) = (PartId(worst.a_id), PartId(worst.b_id));
            // An impact happened along the move, not where the moved part
            // ends: frame the part hit and the point of impact.
            let bounds = match worst.toi {
                Some(_) => scene
                    .part_world_bounds(b)
                    .grown(DVec3::from_array(worst.point)),
                None => scene.part_world_bounds(a).union(scene.part_world_bounds(b)),
            };
            let camera =
                bcf::clash_camera(&bounds, |eye| crate::cmd_render::default_near(&tree, eye));
            let snapshot = match snapshots.as_mut() {
                Some(s) => Some(s.take(&scene, &tree, camera, [a, b]).with_context(|| {
                    format!("rendering the snapshot of {record} step {}", worst.step)
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

/// The topic of one clashing pair, titled with its worst finding.
fn topic(
    scene: &Scene,
    pair: &PairClash,
    record: &str,
    record_name: Option<&str>,
    camera: Camera,
    snapshot: Option<Vec<u8>>,
    clearance: f64,
) -> Topic {
    let worst = pair.worst();
    let (a, b) = (
        scene.part_name(PartId(worst.a_id)),
        scene.part_name(PartId(worst.b_id)),
    );
    let plural = |n: usize| if n == 1 { "" } else { "s" };
    let issue = ClashIssue {
        parts: [a, b],
        described: [
            format!("{a} (#{})", worst.a_id),
            format!("{b} (#{})", worst.b_id),
        ],
        kind: worst.kind,
        distance: worst.distance,
        toi: worst.toi,
        point: DVec3::from_array(worst.point),
        when: bcf::at_step(worst.step, worst.t),
        others: pair.kinds[1..]
            .iter()
            .map(|k| {
                let when = format!(
                    "at {} step{} from step {} (t={})",
                    k.steps,
                    plural(k.steps),
                    k.step,
                    dmu_geom::Short(k.t)
                );
                (k.kind, when)
            })
            .collect(),
        found: format!(
            "Record {record}: the pair has findings at {} step{}, the last at step {} (t={}). \
             Found by dmu collide with clearance {clearance}.",
            pair.steps,
            plural(pair.steps),
            pair.last_step,
            dmu_geom::Short(pair.last_t)
        ),
        prefix: record_name.map_or_else(String::new, |r| format!("{r}: ")),
    };
    issue.topic(
        "dmu collide",
        Viewpoint {
            camera: Some(bcf::Camera::perspective(&camera)),
            selected: vec![
                Component::of(scene, PartId(worst.a_id)),
                Component::of(scene, PartId(worst.b_id)),
            ],
            snapshot: snapshot.map(Into::into),
            ..Viewpoint::new()
        },
    )
}
