//! Pose estimation on a video file (`kind = "video"`, `--source video:FILE` or
//! `video:FILE#PERSON`; needs `rigcast setup vision`).

use std::path::{Path, PathBuf};

use rigcast_protocol::SourceKind;
use serde::Deserialize;

use crate::config::ConfigError;

use super::vision_inputs::{open_file, parse_model, VisionInput, VisionInputs, VisionOptions};
use super::{stem, CliError, KindSpec, Loaded, Opened};

const VIDEO_GRAMMAR: &str =
    "video:FILE or video:FILE#PERSON with a person number (#0 is the first tracked person)";

/// One tracked person of a video file, its frames released in real time.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VideoSpec {
    /// The video.
    pub path: PathBuf,
    /// Which tracked person (`#0`, `#1`, …; default 0). Entries naming the same file share
    /// one decoder and one model run per person per frame.
    pub person: Option<usize>,
    /// People tracked in this video (default 2); `person` must be below it.
    pub people: Option<usize>,
    /// Subject name (default: the file stem, plus `#PERSON` when a person is given).
    pub name: Option<String>,
    /// Landmark model: `lite` (default), `full`, `heavy` or `full-int8`; entries of one file
    /// share it.
    pub model: Option<String>,
}

impl KindSpec for VideoSpec {
    const KIND: SourceKind = SourceKind::Video;
    const CLI: Option<&'static str> = Some("video");

    fn parse_cli(arg: &str) -> Result<Self, CliError> {
        let (path, person) = split_person(arg).map_err(|_| CliError::Expected(VIDEO_GRAMMAR))?;
        if path.is_empty() {
            return Err(CliError::Unknown);
        }
        Ok(VideoSpec {
            path: PathBuf::from(path),
            person,
            people: None,
            name: None,
            model: None,
        })
    }

    fn to_cli(&self) -> Option<String> {
        (self.name.is_none() && self.people.is_none() && self.model.is_none()).then(|| {
            format!(
                "video:{}{}",
                self.path.display(),
                person_suffix(self.person)
            )
        })
    }

    fn file_mut(&mut self) -> Option<&mut PathBuf> {
        Some(&mut self.path)
    }

    fn validate(&self) -> Result<(), ConfigError> {
        parse_model(self.model.as_deref())
            .map(|_| ())
            .map_err(|message| ConfigError::Invalid {
                field: "model",
                message,
            })
    }

    fn open(self) -> anyhow::Result<Opened> {
        self.open_shared(&VisionInputs::default())
    }
}

impl VideoSpec {
    /// Opens this person's subject, sharing the file's pipeline with the other specs of the
    /// same file opened through `vision`.
    pub(crate) fn open_shared(self, vision: &VisionInputs) -> anyhow::Result<Opened> {
        let path = &self.path;
        let input = VisionInput::file(path);
        let options = VisionOptions {
            people: self.people,
            model: parse_model(self.model.as_deref()).map_err(anyhow::Error::msg)?,
        };
        let (source, sk) = vision.person(input, self.person, options, || open_file(path), true)?;
        let name = self
            .name
            .unwrap_or_else(|| stem(path) + &person_suffix(self.person));
        Ok((name, Loaded::live(Box::new(source), SourceKind::Video), sk))
    }
}

/// Splits `FILE#PERSON` at its last `#`. No `#`: no person. A `#` followed by anything but a
/// number is an error, unless the whole text is an existing file (a name that contains `#`).
pub(super) fn split_person(arg: &str) -> Result<(&str, Option<usize>), ()> {
    let Some((head, tail)) = arg.rsplit_once('#') else {
        return Ok((arg, None));
    };
    match tail.parse::<usize>() {
        Ok(person) => Ok((head, Some(person))),
        Err(_) if Path::new(arg).is_file() => Ok((arg, None)),
        Err(_) => Err(()),
    }
}

/// The `#PERSON` of a `--source` argument or default subject name (nothing for the default
/// person).
pub(super) fn person_suffix(person: Option<usize>) -> String {
    person.map(|p| format!("#{p}")).unwrap_or_default()
}
