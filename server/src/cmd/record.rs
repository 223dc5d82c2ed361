//! `rigcast record --url ws://… -o FILE.rcr`: connect as a client and save the stream.

use std::path::PathBuf;

use clap::Args;

/// Options of `rigcast record`.
#[derive(Debug, Args)]
pub struct RecordArgs {
    /// Server stream URL.
    #[arg(long, default_value = "ws://127.0.0.1:8717/v1/stream")]
    pub url: String,
    /// Output recording.
    #[arg(short = 'o', long = "output")]
    pub output: PathBuf,
    /// Stop after this many seconds (default: until Ctrl-C).
    #[arg(long)]
    pub duration: Option<f64>,
}

/// Records.
pub async fn run(_args: RecordArgs) -> anyhow::Result<()> {
    anyhow::bail!("recording is not available yet (waiting for the recording format)")
}
