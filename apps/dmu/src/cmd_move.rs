//! `dmu move`: move one part and write the edited assembly.

use std::path::PathBuf;

use anyhow::bail;
use dmu_tree::{Tree, TreeOptions};
use glam::{DAffine3, DQuat, DVec3};

use crate::load::{ModelArgs, load};
use crate::units::parse_dvec3;

/// Move a part (translate and/or rotate it in world space) and write the model.
///
/// The rotation turns the part about its world bounding-box centre (or its own
/// origin with `--about origin`), then the translation is applied. The cell tree
/// is updated incrementally, as the viewer does while dragging.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    model: ModelArgs,
    /// The part: its name, its full path, or `#id`.
    #[arg(long)]
    part: String,
    /// World translation `x,y,z` (model units).
    #[arg(long, allow_hyphen_values = true, value_parser = parse_dvec3)]
    translate: Option<DVec3>,
    /// Rotation `ax,ay,az,angle` (axis and degrees).
    #[arg(long = "rotate-deg", allow_hyphen_values = true)]
    rotate_deg: Option<String>,
    /// Pivot of the rotation.
    #[arg(long, value_enum, default_value = "center")]
    about: Pivot,
    /// Output file: `.glb` or `.gltf` for glTF, `.dmu` for a store (the input
    /// store itself saves the edit into it). Written to a temporary file and
    /// renamed, so a failure leaves any previous file as it was.
    #[arg(short, long)]
    output: PathBuf,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
enum Pivot {
    /// The part's world bounding-box centre.
    Center,
    /// The part's own origin.
    Origin,
}

fn parse_rotation(s: &str) -> anyhow::Result<DQuat> {
    let v: Vec<f64> = s
        .split(',')
        .map(|p| p.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| anyhow::anyhow!("--rotate-deg {s:?}: expected ax,ay,az,angle"))?;
    let [ax, ay, az, deg] = v.as_slice() else {
        bail!("--rotate-deg {s:?}: expected four numbers ax,ay,az,angle")
    };
    let axis = DVec3::new(*ax, *ay, *az);
    if !(axis.is_finite() && deg.is_finite()) || axis.length_squared() == 0.0 {
        bail!("--rotate-deg {s:?}: the axis must be finite and non-zero");
    }
    Ok(DQuat::from_axis_angle(axis.normalize(), deg.to_radians()))
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    let rotation = args
        .rotate_deg
        .as_deref()
        .map(parse_rotation)
        .transpose()?
        .unwrap_or(DQuat::IDENTITY);
    let translation = args.translate.unwrap_or(DVec3::ZERO);
    let mut loaded = load(&args.model)?;
    let scene = &mut loaded.scene;
    let part = scene.find_part(&args.part)?;
    let mut tree = Tree::build(scene, TreeOptions::default());
    let before = scene.part_world(part);
    let pivot = match args.about {
        Pivot::Center => scene.part_world_bounds(part).center(),
        Pivot::Origin => before.translation,
    };
    let pivot = if pivot.is_finite() {
        pivot
    } else {
        before.translation
    };
    let delta = DAffine3::from_translation(translation + pivot)
        * DAffine3::from_quat(rotation)
        * DAffine3::from_translation(-pivot);
    let after = delta * before;
    if !scene.is_valid_world(part, &after) {
        bail!(
            "{}: the moved part would not be finite or would reach beyond ±{:e} model units",
            args.part,
            dmu_scene::MAX_WORLD_COORDINATE
        );
    }
    let start = std::time::Instant::now();
    tree.move_part(scene, part, after);
    let move_us = start.elapsed().as_secs_f64() * 1e6;
    let format = dmu_store::save_scene(scene, loaded.source.as_deref(), &args.output)?;
    let out = serde_json::json!({
        "part": scene.part_name(part),
        "part_id": part.0,
        "path": scene.part_path(part),
        "translation_before": before.translation.to_array(),
        "translation_after": after.translation.to_array(),
        "bounds_after": { "min": scene.part_world_bounds(part).min.to_array(), "max": scene.part_world_bounds(part).max.to_array() },
        "move_us": move_us,
        "tree": {
            "entries_reinserted": tree.update_stats().reinserted,
            "entries_stayed": tree.update_stats().stayed,
            "cells": tree.cell_count(),
        },
        "output": args.output.display().to_string(),
        "format": format,
    });
    if args.json {
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        println!(
            "moved {} (#{}) from {:?} to {:?} (tree updated in {:.1} µs); wrote {}",
            scene.part_name(part),
            part.0,
            before.translation.to_array(),
            after.translation.to_array(),
            move_us,
            args.output.display()
        );
    }
    Ok(())
}
