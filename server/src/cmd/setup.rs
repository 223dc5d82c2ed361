//! `rigcast setup vision`: installs what the webcam/video pose pipeline needs (ffmpeg, ONNX
//! Runtime, the BlazePose models converted to ONNX, the pose2sim test footage) by running
//! `scripts/setup-vision.sh`, which is embedded in the binary so the command works from any
//! directory. Idempotent: finished steps are skipped.

use std::io::Write;
use std::process::{Command, Stdio};

use clap::{Args, ValueEnum};

/// The setup script, embedded at build time.
const SETUP_VISION: &str = include_str!("../../../scripts/setup-vision.sh");

/// What to set up.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SetupTarget {
    /// ffmpeg, ONNX Runtime, BlazePose models, pose2sim footage (under $RIGCAST_HOME/vision).
    Vision,
}

/// Options of `rigcast setup`.
#[derive(Debug, Args)]
pub struct SetupArgs {
    /// What to install.
    #[arg(value_enum)]
    pub target: SetupTarget,
}

/// Runs the setup script with bash, streaming its output.
pub fn run(args: &SetupArgs) -> anyhow::Result<()> {
    match args.target {
        SetupTarget::Vision => {
            let mut child = Command::new("bash")
                .args(["-s", "--"])
                .stdin(Stdio::piped())
                .spawn()
                .map_err(|e| anyhow::anyhow!("cannot run bash for the vision setup: {e}"))?;
            if let Some(mut stdin) = child.stdin.take() {
                stdin.write_all(SETUP_VISION.as_bytes())?;
            }
            let status = child.wait()?;
            if !status.success() {
                anyhow::bail!("vision setup failed ({status})");
            }
            Ok(())
        }
    }
}
