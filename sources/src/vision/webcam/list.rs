//! The cameras of this machine and the modes each offers, read from the V4L2 driver without
//! changing anything (no format is set, no stream started), so listing works while another
//! program (or this server) is streaming from the camera.

use v4l::frameinterval::FrameIntervalEnum;
use v4l::framesize::FrameSizeEnum;
use v4l::video::Capture;
use v4l::{Device, FourCC};

use super::super::camera_modes::{CameraMode, PixelFormat};

/// Sizes per format and rates per size read at most (a hostile or broken driver could
/// enumerate without end).
const MAX_ENUM: usize = 256;

/// One capture camera.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CameraInfo {
    /// The index of `webcam:INDEX` (the N of `/dev/videoN`).
    pub index: u32,
    /// What the driver calls the camera.
    pub name: String,
    /// Every mode offered in a format rigcast decodes, sorted.
    pub modes: Vec<CameraMode>,
    /// Formats offered that rigcast does not decode (four-character codes).
    pub other_formats: Vec<String>,
}

/// Every video-capture device (metadata and output nodes are skipped), by index.
pub fn list_cameras() -> Vec<CameraInfo> {
    let mut cameras: Vec<CameraInfo> = v4l::context::enum_devices()
        .iter()
        .filter_map(|node| {
            let index = u32::try_from(index_of(node.path())?).ok()?;
            let fallback = node.name();
            describe(index, fallback).ok().flatten()
        })
        .collect();
    cameras.sort_by_key(|c| c.index);
    cameras
}

/// The number in `/dev/videoN` (v4l's own parser panics on a name without digits).
fn index_of(path: &std::path::Path) -> Option<usize> {
    path.file_name()?
        .to_str()?
        .strip_prefix("video")?
        .parse()
        .ok()
}

/// Camera `index`, or None when it is not a video-capture device.
fn describe(index: u32, fallback_name: Option<String>) -> std::io::Result<Option<CameraInfo>> {
    let dev = Device::new(index as usize)?;
    let caps = dev.query_caps()?;
    if !caps
        .capabilities
        .contains(v4l::capability::Flags::VIDEO_CAPTURE)
    {
        return Ok(None);
    }
    let mut modes = Vec::new();
    let mut other_formats = Vec::new();
    for desc in dev.enum_formats()? {
        let Some(format) = pixel_format(desc.fourcc) else {
            other_formats.push(desc.fourcc.str().unwrap_or("????").to_string());
            continue;
        };
        for (w, h) in sizes(&dev, desc.fourcc) {
            for fps in rates(&dev, desc.fourcc, w, h) {
                modes.push(CameraMode {
                    width: w,
                    height: h,
                    fps,
                    format,
                });
            }
        }
    }
    modes.sort();
    modes.dedup();
    let name = if caps.card.is_empty() {
        fallback_name.unwrap_or_else(|| format!("/dev/video{index}"))
    } else {
        caps.card
    };
    Ok(Some(CameraInfo {
        index,
        name,
        modes,
        other_formats,
    }))
}

/// The pixel format of a four-character code rigcast decodes.
pub(super) fn pixel_format(fourcc: FourCC) -> Option<PixelFormat> {
    PixelFormat::parse(fourcc.str().ok()?)
}

/// Frame sizes of `fourcc`; a stepwise range contributes its ends.
fn sizes(dev: &Device, fourcc: FourCC) -> Vec<(u32, u32)> {
    let mut out = Vec::new();
    for size in dev
        .enum_framesizes(fourcc)
        .unwrap_or_default()
        .into_iter()
        .take(MAX_ENUM)
    {
        match size.size {
            FrameSizeEnum::Discrete(d) => out.push((d.width, d.height)),
            FrameSizeEnum::Stepwise(s) => {
                out.push((s.min_width, s.min_height));
                out.push((s.max_width, s.max_height));
            }
        }
    }
    out
}

/// Whole frame rates offered at `w`×`h` (V4L2 gives intervals: 1/30 s is 30 fps).
fn rates(dev: &Device, fourcc: FourCC, w: u32, h: u32) -> Vec<u32> {
    let whole = |num: u32, den: u32| (num > 0 && den.is_multiple_of(num)).then(|| den / num);
    let mut out = Vec::new();
    for iv in dev
        .enum_frameintervals(fourcc, w, h)
        .unwrap_or_default()
        .into_iter()
        .take(MAX_ENUM)
    {
        match iv.interval {
            FrameIntervalEnum::Discrete(f) => out.extend(whole(f.numerator, f.denominator)),
            // A continuous range: its fastest and slowest ends.
            FrameIntervalEnum::Stepwise(s) => {
                out.extend(whole(s.min.numerator, s.min.denominator));
                out.extend(whole(s.max.numerator, s.max.denominator));
            }
        }
    }
    out
}

/// `0 (Name), 2 (Other)` for a message, or `none` when there is no camera.
pub fn describe_cameras(cameras: &[CameraInfo]) -> String {
    if cameras.is_empty() {
        return "none (no /dev/video* capture device is present and readable)".into();
    }
    cameras
        .iter()
        .map(|c| format!("{} ({})", c.index, c.name))
        .collect::<Vec<_>>()
        .join(", ")
}
