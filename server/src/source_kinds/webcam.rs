//! Pose estimation on a webcam (`kind = "webcam"`, `--source webcam:INDEX`; needs
//! `rigcast setup vision` and a build with `--features webcam`).

use rigcast_protocol::SourceKind;
use serde::Deserialize;

use super::{CliError, KindSpec, Opened};

/// What to tell a user of a build without webcam support.
pub const NO_WEBCAM_HINT: &str = "this rigcast was built without webcam support; rebuild it with \
     `cargo build --release -p rigcast-server --features webcam` (which needs libclang: \
     `sudo apt-get install libclang-dev` on Debian/Ubuntu), or use `--source video:FILE`";

const WEBCAM_GRAMMAR: &str = "webcam:INDEX with a camera number, e.g. webcam:0";

/// A camera by index.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WebcamSpec {
    /// Camera index (default 0: the first camera).
    #[serde(default)]
    pub index: u32,
    /// Subject name (default `webcam:INDEX`).
    pub name: Option<String>,
}

impl KindSpec for WebcamSpec {
    const KIND: SourceKind = SourceKind::Webcam;
    const CLI: Option<&'static str> = Some("webcam");

    fn parse_cli(arg: &str) -> Result<Self, CliError> {
        let index = arg
            .parse()
            .map_err(|_| CliError::Expected(WEBCAM_GRAMMAR))?;
        Ok(WebcamSpec { index, name: None })
    }

    fn to_cli(&self) -> Option<String> {
        self.name
            .is_none()
            .then(|| format!("webcam:{}", self.index))
    }

    fn open(self) -> anyhow::Result<Opened> {
        open(self)
    }
}

/// A camera delivers frames as they happen: no pacing (realtime = false).
#[cfg(feature = "webcam")]
fn open(spec: WebcamSpec) -> anyhow::Result<Opened> {
    use anyhow::Context;
    use rigcast_sources::vision::{open_webcam, VisionSource};
    let index = spec.index;
    let frames = open_webcam(index).with_context(|| format!("cannot open webcam {index}"))?;
    let pipeline = super::video::pose_pipeline()?;
    let sk = pipeline.skeleton().clone();
    let source = VisionSource::new(format!("webcam:{index}"), frames, pipeline, false);
    let name = spec.name.unwrap_or_else(|| format!("webcam:{index}"));
    let loaded = super::Loaded::live(Box::new(source), SourceKind::Webcam);
    Ok((name, loaded, sk))
}

/// Without the `webcam` feature: a clear error saying how to get one.
#[cfg(not(feature = "webcam"))]
fn open(spec: WebcamSpec) -> anyhow::Result<Opened> {
    anyhow::bail!("--source webcam:{}: {NO_WEBCAM_HINT}", spec.index)
}
