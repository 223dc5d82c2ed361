//! Pose estimation on a webcam (`kind = "webcam"`, `--source webcam:INDEX` or
//! `webcam:INDEX#PERSON`; needs `rigcast setup vision` and a build with `--features webcam`).

use rigcast_protocol::SourceKind;
use serde::Deserialize;

use super::video::{person_suffix, split_person};
use super::vision_inputs::VisionInputs;
use super::{CliError, KindSpec, Opened};

/// What to tell a user of a build without webcam support.
pub const NO_WEBCAM_HINT: &str = "this rigcast was built without webcam support; rebuild it with \
     `cargo build --release -p rigcast-server --features webcam` (which needs libclang: \
     `sudo apt-get install libclang-dev` on Debian/Ubuntu), or use `--source video:FILE`";

const WEBCAM_GRAMMAR: &str =
    "webcam:INDEX or webcam:INDEX#PERSON with a camera number and a person number, e.g. webcam:0#1";

/// One tracked person of a camera by index.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WebcamSpec {
    /// Camera index (default 0: the first camera).
    #[serde(default)]
    pub index: u32,
    /// Which tracked person, as for `video` (default 0).
    pub person: Option<usize>,
    /// People tracked on this camera (default 2).
    pub people: Option<usize>,
    /// Subject name (default `webcam:INDEX`, plus `#PERSON` when a person is given).
    pub name: Option<String>,
}

impl KindSpec for WebcamSpec {
    const KIND: SourceKind = SourceKind::Webcam;
    const CLI: Option<&'static str> = Some("webcam");

    fn parse_cli(arg: &str) -> Result<Self, CliError> {
        let bad = CliError::Expected(WEBCAM_GRAMMAR);
        let (index, person) = split_person(arg).map_err(|_| bad)?;
        Ok(WebcamSpec {
            index: index.parse().map_err(|_| bad)?,
            person,
            people: None,
            name: None,
        })
    }

    fn to_cli(&self) -> Option<String> {
        (self.name.is_none() && self.people.is_none())
            .then(|| format!("webcam:{}{}", self.index, person_suffix(self.person)))
    }

    fn open(self) -> anyhow::Result<Opened> {
        self.open_shared(&VisionInputs::default())
    }
}

impl WebcamSpec {
    /// Opens this person's subject, sharing the camera's pipeline with the other specs of the
    /// same camera opened through `vision`. A camera delivers frames as they happen: no
    /// pacing (realtime = false).
    #[cfg(feature = "webcam")]
    pub(crate) fn open_shared(self, vision: &VisionInputs) -> anyhow::Result<Opened> {
        use anyhow::Context;
        let index = self.index;
        let open = || {
            rigcast_sources::vision::open_webcam(index)
                .with_context(|| format!("cannot open webcam {index}"))
        };
        let input = super::vision_inputs::VisionInput::Webcam(index);
        let (source, sk) = vision.person(input, self.person, self.people, open, false)?;
        let loaded = super::Loaded::live(Box::new(source), SourceKind::Webcam);
        let name = self
            .name
            .unwrap_or_else(|| format!("webcam:{index}{}", person_suffix(self.person)));
        Ok((name, loaded, sk))
    }

    /// Without the `webcam` feature: a clear error saying how to get one.
    #[cfg(not(feature = "webcam"))]
    pub(crate) fn open_shared(self, _vision: &VisionInputs) -> anyhow::Result<Opened> {
        anyhow::bail!("--source webcam:{}: {NO_WEBCAM_HINT}", self.index)
    }
}
