//! `rigcast record --url ws://… -o FILE.rcr [--duration SECS]`: connect to a server as an
//! ordinary client and save what it streams as a recording (`stream_record`).

use std::path::PathBuf;
use std::time::Duration;

use anyhow::bail;
use clap::Args;

use crate::stream_record::record;

/// Options of `rigcast record`.
#[derive(Debug, Args)]
pub struct RecordArgs {
    /// Server stream URL.
    #[arg(long, default_value = "ws://127.0.0.1:8717/v1/stream")]
    pub url: String,
    /// Output recording (.rcr).
    #[arg(short = 'o', long = "output")]
    pub output: PathBuf,
    /// Stop after this many seconds (default: until Ctrl-C or the server closes).
    #[arg(long)]
    pub duration: Option<f64>,
}

/// Records until Ctrl-C, the duration, or the server closing.
pub async fn run(args: RecordArgs) -> anyhow::Result<()> {
    if let Some(d) = args.duration {
        // A finite 1e300 is still no `Duration`.
        if !(d > 0.0 && Duration::try_from_secs_f64(d).is_ok()) {
            bail!("--duration must be a positive number of seconds (under 5e11 years), got {d:?}");
        }
    }
    let stop = async {
        match args.duration {
            Some(secs) => tokio::time::sleep(Duration::from_secs_f64(secs)).await,
            None => {
                // This fails only when no Ctrl-C handler can be installed; the recording then ends at
                // once, its file complete, rather than run with no clean way to stop it.
                let _ = tokio::signal::ctrl_c().await;
            }
        }
    };
    let summary = record(&args.url, &args.output, stop).await?;
    println!(
        "wrote {}: {} skeleton(s), {} frame(s)",
        args.output.display(),
        summary.skeletons,
        summary.frames
    );
    Ok(())
}
