//! The command line: one [`Command`] variant per subcommand, each implemented in its own
//! module under [`crate::cmd`]. To add a subcommand: add a module in `cmd/`, a variant here with
//! its `Args` struct, and one arm in [`Command::run`].

use clap::{Parser, Subcommand};

use crate::cmd;

/// rigcast — realtime puppetry server.
#[derive(Debug, Parser)]
#[command(
    name = "rigcast",
    version,
    about = "rigcast — realtime puppetry: performer motion in (files, VMC/OSC, serial IMU suits, video), retargeted onto any character skeleton, streamed out (WebSocket, VMC, recordings)",
    args_conflicts_with_subcommands = true
)]
pub struct Cli {
    /// What to do; without a subcommand rigcast serves (the bundled demo unless `--source`).
    #[command(subcommand)]
    pub command: Option<Command>,
    /// `serve` options, accepted without the subcommand (`rigcast --listen 127.0.0.1:0`).
    #[command(flatten)]
    pub serve: cmd::serve::ServeArgs,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Stream poses over WebSocket (and VMC) — the default.
    Serve(cmd::serve::ServeArgs),
    /// List cameras (index, name, modes), serial ports and the VMC ports in use.
    Devices(cmd::devices::DevicesArgs),
    /// Describe an animation file: bone tree, height, frame rate, duration.
    Info(cmd::info::InfoArgs),
    /// Convert between animation formats (chosen by extension).
    Convert(cmd::convert::ConvertArgs),
    /// Record what a server streams into a .rcr recording.
    Record(cmd::record::RecordArgs),
    /// Put an animation onto another character (offline), written as BVH or GLB.
    Retarget(cmd::retarget::RetargetArgs),
    /// Graft the upper body of one clip onto another's legs, in step with its footplants.
    Graft(cmd::graft::GraftArgs),
    /// Measure the realtime path (retarget, FK, mapping build, frame encode) on this machine.
    Bench(cmd::bench::BenchArgs),
    /// Map the bones of SOURCE onto TARGET automatically (table, or --json).
    Map(cmd::map::MapArgs),
    /// Extract BlazePose landmarks (--json) and/or BVH motion (-o) from a video offline.
    Pose(cmd::pose::PoseArgs),
    /// Install optional components (`rigcast setup vision`).
    Setup(cmd::setup::SetupArgs),
    /// Calibrate a running server's serial IMU suit: hold a T- or N-pose, capture offsets.
    Calibrate(cmd::calibrate::CalibrateArgs),
    /// Show or rotate the control token (needed to change mappings or calibrate).
    Token(cmd::token::TokenArgs),
    /// Motion graphs: build from clips, walk between poses, describe (`rigcast graph --help`).
    Graph(cmd::graph::GraphArgs),
    /// Open many clients on a running server and report their frame rate and latency.
    Loadtest(cmd::loadtest::LoadtestArgs),
}

impl Command {
    /// True for the subcommands that open no socket: they read files and write to stdout and
    /// files only (the live ones — serve, record, calibrate, loadtest — talk to servers).
    pub fn is_offline(&self) -> bool {
        !matches!(
            self,
            Command::Serve(_) | Command::Record(_) | Command::Calibrate(_) | Command::Loadtest(_)
        )
    }

    /// Runs the subcommand.
    pub async fn run(self) -> anyhow::Result<()> {
        match self {
            Command::Serve(a) => cmd::serve::run(a).await,
            Command::Info(a) => cmd::info::run(a),
            Command::Devices(a) => cmd::devices::run(&a),
            Command::Convert(a) => cmd::convert::run(a),
            Command::Record(a) => cmd::record::run(a).await,
            Command::Retarget(a) => cmd::retarget::run(&a),
            Command::Graft(a) => cmd::graft::run(&a),
            Command::Bench(a) => cmd::bench::run(&a),
            Command::Map(a) => cmd::map::run(&a),
            Command::Pose(a) => cmd::pose::run(&a),
            Command::Setup(a) => cmd::setup::run(&a),
            Command::Calibrate(a) => cmd::calibrate::run(a).await,
            Command::Token(a) => cmd::token::run(&a),
            Command::Loadtest(a) => cmd::loadtest::run(a).await,
            Command::Graph(a) => cmd::graph::run(&a),
        }
    }
}

impl Cli {
    /// The subcommand, defaulting to `serve` with the top-level options.
    pub fn command_or_default(self) -> Command {
        match self.command {
            Some(c) => c,
            None => Command::Serve(self.serve),
        }
    }
}
