//! `rigcast retarget` run as the binary users run, with the options a test sets.

use std::path::PathBuf;
use std::process::Command;

/// The command's options, as `rigcast retarget --help` lists them.
pub struct RetargetArgs {
    pub anim: PathBuf,
    pub target: PathBuf,
    pub output: PathBuf,
    pub mapping: Option<PathBuf>,
    pub fps: Option<f64>,
    pub in_place: bool,
    pub no_foot_lock: bool,
}

/// Runs `rigcast retarget`; when it fails, the error is what it printed on stderr.
pub fn run(args: &RetargetArgs) -> anyhow::Result<()> {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_rigcast"));
    cmd.arg("retarget")
        .arg(&args.anim)
        .arg("--target")
        .arg(&args.target)
        .arg("-o")
        .arg(&args.output);
    if let Some(m) = &args.mapping {
        cmd.arg("--mapping").arg(m);
    }
    if let Some(fps) = args.fps {
        cmd.arg("--fps").arg(fps.to_string());
    }
    if args.in_place {
        cmd.arg("--in-place");
    }
    if args.no_foot_lock {
        cmd.arg("--no-foot-lock");
    }
    let out = cmd.output()?;
    if out.status.success() {
        Ok(())
    } else {
        anyhow::bail!("{}", String::from_utf8_lossy(&out.stderr))
    }
}
