//! `dmu`: the command line of the dmu digital-mockup viewer.

mod bench_collide;
mod bench_pick;
mod cmd_bcf;
mod cmd_bench;
mod cmd_collide;
mod cmd_farfield;
mod cmd_generate;
mod cmd_import;
mod cmd_info;
mod cmd_lod;
mod cmd_move;
mod cmd_pick;
mod cmd_render;
mod cmd_tradeoffs;
mod cmd_walk;
mod collide_batch;
mod collide_bcf;
mod stereo_far;
mod tradeoffs;
mod walk_render;

use std::process::ExitCode;

use clap::{Parser, Subcommand};
// Opening models, parsing units and progress live in dmu-app, shared with dmu-viewer.
use dmu_app::{load, progress, resident, text, units};

/// dmu: walk, pick, move and clash-check massive CAD assemblies.
///
/// Commands that take a FILE read glTF 2.0 (.glb, .gltf) or a dmu store (.dmu);
/// with no FILE they use the built-in procedural plant. Exit codes: 0 success, 1 clashes found (collide),
/// 2 error.
#[derive(Debug, Parser)]
#[command(name = "dmu", version, about, long_about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    #[command(flatten)]
    remote: dmu_app::remote::RemoteArgs,
}

#[derive(Debug, Subcommand)]
enum Command {
    Generate(cmd_generate::Args),
    Info(cmd_info::Args),
    Import(cmd_import::Args),
    Pick(cmd_pick::Args),
    Move(cmd_move::Args),
    Collide(cmd_collide::Args),
    Bcf(cmd_bcf::Args),
    Render(cmd_render::Args),
    Walk(cmd_walk::Args),
    Bench(cmd_bench::Args),
    Tradeoffs(cmd_tradeoffs::Args),
    Farfield(cmd_farfield::Args),
    Lod(cmd_lod::Args),
}

/// Ends the process quietly, as Unix tools do, when the reader of stdout goes
/// away (`dmu info --json | head -c 1`), instead of panicking in `println!`.
#[cfg(unix)]
#[expect(
    unsafe_code,
    reason = "restoring the default SIGPIPE action is one libc call"
)]
fn die_on_closed_pipe() {
    // SAFETY: called first thing in `main`, before any other thread exists;
    // SIG_DFL is a valid action for SIGPIPE.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

#[expect(unsafe_code, reason = "quiet_device_select runs before any thread")]
fn main() -> ExitCode {
    // SAFETY: first in main, while the process has one thread.
    unsafe { dmu_app::quiet_device_select() };
    #[cfg(unix)]
    die_on_closed_pipe();
    let cli = Cli::parse();
    cli.remote.apply();
    let result = match cli.command {
        Command::Generate(args) => cmd_generate::run(&args),
        Command::Info(args) => cmd_info::run(&args),
        Command::Import(args) => cmd_import::run(&args),
        Command::Pick(args) => cmd_pick::run(&args),
        Command::Move(args) => cmd_move::run(&args),
        Command::Collide(args) => match cmd_collide::run(&args) {
            Ok(code) => return code,
            Err(e) => Err(e),
        },
        Command::Bcf(args) => cmd_bcf::run(&args),
        Command::Render(args) => cmd_render::run(&args),
        Command::Walk(args) => cmd_walk::run(&args),
        Command::Bench(args) => cmd_bench::run(&args),
        Command::Tradeoffs(args) => cmd_tradeoffs::run(&args),
        Command::Farfield(args) => cmd_farfield::run(&args),
        Command::Lod(args) => cmd_lod::run(&args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("{}", dmu_app::text::error_line("dmu", &e));
            ExitCode::from(2)
        }
    }
}
