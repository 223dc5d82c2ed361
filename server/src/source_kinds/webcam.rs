//! Pose estimation on a webcam (`kind = "webcam"`, `--source webcam:INDEX`,
//! `webcam:INDEX#PERSON`, `webcam:INDEX?width=1280&height=720&fps=60&format=mjpeg`; needs
//! `rigcast setup vision`; the default build has webcam support).

use rigcast_protocol::SourceKind;
use rigcast_sources::vision::{camera_modes, PixelFormat, WebcamOptions};
use serde::Deserialize;

use crate::config::ConfigError;

use super::video::{person_suffix, split_person};
use super::vision_inputs::{parse_model, VisionInputs};
use super::{CliError, KindSpec, Opened};

/// What to tell a user of a build without webcam support.
pub const NO_WEBCAM_HINT: &str = "this rigcast was built without webcam support \
     (`--no-default-features`); rebuild it with the default features (which need libclang: \
     scripts/install-apps.sh installs it on Debian/Ubuntu), or use `--source video:FILE`";

const WEBCAM_GRAMMAR: &str = "webcam:INDEX or webcam:INDEX#PERSON with a camera number (see \
     `rigcast devices`) and a person number, optionally followed by \
     ?width=W&height=H&fps=F&format=yuyv|mjpeg&model=lite|full, e.g. webcam:0#1 or \
     webcam:0?width=1280&fps=60&model=full";

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
    /// Wanted width in pixels (default: the camera's nearest to 640×480).
    pub width: Option<u32>,
    /// Wanted height in pixels.
    pub height: Option<u32>,
    /// Wanted frames per second (default: the highest at the chosen size).
    pub fps: Option<u32>,
    /// Wanted pixel format, `yuyv` or `mjpeg` (default: YUYV when it offers the rate).
    pub format: Option<String>,
    /// Landmark model: `lite` (default: the fastest), `full`, `heavy` or `full-int8`.
    pub model: Option<String>,
}

impl WebcamSpec {
    /// The camera options of this spec (formats already checked by `validate`).
    pub fn options(&self) -> WebcamOptions {
        WebcamOptions {
            width: self.width,
            height: self.height,
            fps: self.fps,
            format: self.format.as_deref().and_then(PixelFormat::parse),
        }
    }
}

impl KindSpec for WebcamSpec {
    const KIND: SourceKind = SourceKind::Webcam;
    const CLI: Option<&'static str> = Some("webcam");

    fn parse_cli(arg: &str) -> Result<Self, CliError> {
        let bad = CliError::Expected(WEBCAM_GRAMMAR);
        let (camera, query) = arg.split_once('?').unwrap_or((arg, ""));
        let (index, person) = split_person(camera).map_err(|_| bad)?;
        // `model` is the pipeline's; the rest are the camera's.
        let mut model = None;
        let mut camera_query = String::new();
        for pair in query.split('&').filter(|p| !p.is_empty()) {
            match pair.strip_prefix("model=") {
                Some(m) => model = Some(m.to_string()),
                None => {
                    if !camera_query.is_empty() {
                        camera_query.push('&');
                    }
                    camera_query.push_str(pair);
                }
            }
        }
        parse_model(model.as_deref()).map_err(|_| bad)?;
        let o = WebcamOptions::parse_query(&camera_query).map_err(|_| bad)?;
        Ok(WebcamSpec {
            index: index.parse().map_err(|_| bad)?,
            person,
            people: None,
            name: None,
            width: o.width,
            height: o.height,
            fps: o.fps,
            format: o.format.map(|f| f.name().to_string()),
            model,
        })
    }

    fn to_cli(&self) -> Option<String> {
        let mut query = self.options().to_query();
        if let Some(m) = &self.model {
            if !query.is_empty() {
                query.push('&');
            }
            query.push_str(&format!("model={m}"));
        }
        let query = if query.is_empty() {
            query
        } else {
            format!("?{query}")
        };
        (self.name.is_none() && self.people.is_none())
            .then(|| format!("webcam:{}{}{query}", self.index, person_suffix(self.person)))
    }

    fn validate(&self) -> Result<(), ConfigError> {
        let bounded = |field, v: Option<u32>, max| match v {
            Some(v) if !(1..=max).contains(&v) => Err(ConfigError::Invalid {
                field,
                message: format!("{v} must be 1..={max}"),
            }),
            _ => Ok(()),
        };
        bounded("width", self.width, camera_modes::MAX_SIDE)?;
        bounded("height", self.height, camera_modes::MAX_SIDE)?;
        bounded("fps", self.fps, camera_modes::MAX_FPS)?;
        if let Err(message) = parse_model(self.model.as_deref()) {
            return Err(ConfigError::Invalid {
                field: "model",
                message,
            });
        }
        match self.format.as_deref() {
            Some(f) if PixelFormat::parse(f).is_none() => Err(ConfigError::Invalid {
                field: "format",
                message: format!("{f:?}: expected yuyv or mjpeg"),
            }),
            _ => Ok(()),
        }
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
        let options = self.options();
        let open = || {
            rigcast_sources::vision::open_webcam(index, options)
                .with_context(|| format!("cannot open webcam {index}"))
        };
        let input = super::vision_inputs::VisionInput::Webcam(index);
        let options = super::vision_inputs::VisionOptions {
            people: self.people,
            model: parse_model(self.model.as_deref()).map_err(anyhow::Error::msg)?,
        };
        let (source, sk) = vision.person(input, self.person, options, open, false)?;
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
