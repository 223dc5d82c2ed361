//! Camera modes (size, frame rate, pixel format) and the choice of one from what a camera
//! offers and what the performer asked for (`webcam:0?width=1280&height=720&fps=60`).
//!
//! The choice is pure (no device) so it is the same on every platform and unit-tested here;
//! the webcam source feeds it the modes the driver enumerates.

use std::fmt;

/// Pixel formats rigcast decodes from a camera (what the V4L2 driver delivers).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum PixelFormat {
    /// Packed 4:2:2 YUV (`YUYV`): uncompressed, cheapest to decode.
    Yuyv,
    /// Motion JPEG (`MJPG`): what USB cameras use for large sizes at high rates.
    Mjpeg,
}

impl PixelFormat {
    /// The V4L2 four-character code.
    pub fn fourcc(self) -> &'static str {
        match self {
            PixelFormat::Yuyv => "YUYV",
            PixelFormat::Mjpeg => "MJPG",
        }
    }

    /// The name options use (`yuyv`, `mjpeg`).
    pub fn name(self) -> &'static str {
        match self {
            PixelFormat::Yuyv => "yuyv",
            PixelFormat::Mjpeg => "mjpeg",
        }
    }

    /// Parses a four-character code or a common name (`yuyv`, `mjpeg`, `mjpg`).
    pub fn parse(text: &str) -> Option<PixelFormat> {
        match text.to_ascii_lowercase().as_str() {
            "yuyv" | "yuy2" => Some(PixelFormat::Yuyv),
            "mjpg" | "mjpeg" => Some(PixelFormat::Mjpeg),
            _ => None,
        }
    }
}

impl fmt::Display for PixelFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.fourcc())
    }
}

/// One mode a camera offers: a size at a whole frame rate in a pixel format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct CameraMode {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Frames per second.
    pub fps: u32,
    /// Pixel format.
    pub format: PixelFormat,
}

impl fmt::Display for CameraMode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}x{}@{} {}",
            self.width, self.height, self.fps, self.format
        )
    }
}

/// What the performer asked of a camera; anything unset is chosen (see [`choose_mode`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct WebcamOptions {
    /// Wanted width in pixels.
    pub width: Option<u32>,
    /// Wanted height in pixels.
    pub height: Option<u32>,
    /// Wanted frames per second.
    pub fps: Option<u32>,
    /// Wanted pixel format.
    pub format: Option<PixelFormat>,
}

/// The size aimed at when none is asked: the pose model sees at most 256 pixels a side, so
/// larger frames only cost decode time; 640×480 is what every camera offers.
pub const DEFAULT_SIZE: (u32, u32) = (640, 480);

/// Largest width or height accepted in options (bounds what a typo can ask for).
pub const MAX_SIDE: u32 = 16384;

/// Largest frame rate accepted in options.
pub const MAX_FPS: u32 = 1000;

impl WebcamOptions {
    /// Parses `width=1280&height=720&fps=60&format=mjpeg` (the part after `?` of a source).
    pub fn parse_query(query: &str) -> Result<WebcamOptions, String> {
        let mut o = WebcamOptions::default();
        for pair in query.split('&').filter(|p| !p.is_empty()) {
            let (key, value) = pair
                .split_once('=')
                .ok_or_else(|| format!("camera option {pair:?} is not KEY=VALUE"))?;
            match key {
                "width" => o.width = Some(parse_bounded(key, value, MAX_SIDE)?),
                "height" => o.height = Some(parse_bounded(key, value, MAX_SIDE)?),
                "fps" => o.fps = Some(parse_bounded(key, value, MAX_FPS)?),
                "format" => {
                    o.format = Some(PixelFormat::parse(value).ok_or_else(|| {
                        format!("camera format {value:?}: expected yuyv or mjpeg")
                    })?)
                }
                _ => {
                    return Err(format!(
                        "unknown camera option {key:?}; expected width, height, fps or format"
                    ))
                }
            }
        }
        Ok(o)
    }

    /// The query string these options parse from (empty when nothing is asked).
    pub fn to_query(&self) -> String {
        let mut parts = Vec::new();
        if let Some(w) = self.width {
            parts.push(format!("width={w}"));
        }
        if let Some(h) = self.height {
            parts.push(format!("height={h}"));
        }
        if let Some(f) = self.fps {
            parts.push(format!("fps={f}"));
        }
        if let Some(f) = self.format {
            parts.push(format!("format={}", f.name()));
        }
        parts.join("&")
    }
}

fn parse_bounded(key: &str, value: &str, max: u32) -> Result<u32, String> {
    match value.parse::<u32>() {
        Ok(v) if (1..=max).contains(&v) => Ok(v),
        _ => Err(format!(
            "camera option {key}={value:?}: expected a number 1..={max}"
        )),
    }
}

/// The mode picked for a request, and what of the request it could not give.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Choice {
    /// The mode to open.
    pub mode: CameraMode,
    /// One line per asked value the camera does not offer (empty when all were met).
    pub fallbacks: Vec<String>,
}

/// Picks a mode of `offered` for `asked`, in order of what matters to a performer:
/// 1. the pixel format, if asked (an error when the camera has none of it);
/// 2. the size nearest the asked one (the default 640×480 when none is asked; a missing
///    width or height follows the other at the camera's aspect), nearness being the
///    log-ratio of widths plus that of heights, so 2× too big weighs as much as 2× too small;
/// 3. at that size, the frame rate nearest the asked one, or the highest offered;
/// 4. at that size and rate, YUYV before MJPEG (no lossy compression, cheaper to decode).
///
/// Ties go to the larger size and the higher rate.
pub fn choose_mode(offered: &[CameraMode], asked: &WebcamOptions) -> Result<Choice, String> {
    let usable: Vec<CameraMode> = offered
        .iter()
        .copied()
        .filter(|m| asked.format.is_none_or(|f| m.format == f))
        .collect();
    if usable.is_empty() {
        return Err(match asked.format {
            Some(f) if !offered.is_empty() => format!(
                "the camera offers no {f} mode (it offers {})",
                describe_formats(offered)
            ),
            _ => "the camera offers no mode rigcast can decode (YUYV or MJPEG)".into(),
        });
    }
    let (want_w, want_h) = wanted_size(&usable, asked);
    let size_cost = |m: &CameraMode| {
        let lw = (m.width as f64 / want_w).ln().abs();
        let lh = (m.height as f64 / want_h).ln().abs();
        lw + lh
    };
    let best_size = usable
        .iter()
        .min_by(|a, b| {
            size_cost(a)
                .total_cmp(&size_cost(b))
                .then((b.width * b.height).cmp(&(a.width * a.height)))
        })
        .map(|m| (m.width, m.height))
        .ok_or("no mode")?;
    let at_size = usable
        .iter()
        .filter(|m| (m.width, m.height) == best_size)
        .copied();
    let mode = at_size
        .min_by_key(|m| {
            let rate = match asked.fps {
                Some(f) => (m.fps.abs_diff(f), u32::MAX - m.fps),
                None => (0, u32::MAX - m.fps),
            };
            (rate, m.format)
        })
        .ok_or("no mode")?;
    let mut fallbacks = Vec::new();
    let size_asked = asked.width.is_some() || asked.height.is_some();
    if size_asked
        && (asked.width.is_some_and(|w| w != mode.width)
            || asked.height.is_some_and(|h| h != mode.height))
    {
        fallbacks.push(format!(
            "no {}x{} mode; using the nearest size, {}x{}",
            show(asked.width),
            show(asked.height),
            mode.width,
            mode.height
        ));
    }
    if let Some(f) = asked.fps.filter(|f| *f != mode.fps) {
        fallbacks.push(format!(
            "no {f} fps at {}x{}; using the nearest rate, {} fps",
            mode.width, mode.height, mode.fps
        ));
    }
    Ok(Choice { mode, fallbacks })
}

fn show(v: Option<u32>) -> String {
    v.map_or_else(|| "*".to_string(), |v| v.to_string())
}

/// The size to aim at: the asked one, completing a lone width or height at the aspect of the
/// camera's largest mode.
fn wanted_size(usable: &[CameraMode], asked: &WebcamOptions) -> (f64, f64) {
    let largest = usable
        .iter()
        .max_by_key(|m| m.width * m.height)
        .map_or((4.0, 3.0), |m| (m.width as f64, m.height as f64));
    let aspect = largest.0 / largest.1.max(1.0);
    match (asked.width, asked.height) {
        (Some(w), Some(h)) => (w as f64, h as f64),
        (Some(w), None) => (w as f64, w as f64 / aspect),
        (None, Some(h)) => (h as f64 * aspect, h as f64),
        (None, None) => (DEFAULT_SIZE.0 as f64, DEFAULT_SIZE.1 as f64),
    }
}

/// `YUYV, MJPG`: the distinct formats of `modes`.
pub fn describe_formats(modes: &[CameraMode]) -> String {
    let mut formats: Vec<PixelFormat> = modes.iter().map(|m| m.format).collect();
    formats.sort();
    formats.dedup();
    formats
        .iter()
        .map(|f| f.fourcc())
        .collect::<Vec<_>>()
        .join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn m(width: u32, height: u32, fps: u32, format: PixelFormat) -> CameraMode {
        CameraMode {
            width,
            height,
            fps,
            format,
        }
    }

    /// What a typical USB camera offers: YUYV only up to 640×480 at 30, MJPEG up to 720p60.
    fn usb() -> Vec<CameraMode> {
        use PixelFormat::*;
        vec![
            m(640, 480, 30, Yuyv),
            m(320, 240, 30, Yuyv),
            m(1280, 720, 10, Yuyv),
            m(640, 480, 30, Mjpeg),
            m(640, 480, 60, Mjpeg),
            m(1280, 720, 30, Mjpeg),
            m(1280, 720, 60, Mjpeg),
        ]
    }

    fn ask(width: Option<u32>, height: Option<u32>, fps: Option<u32>) -> WebcamOptions {
        WebcamOptions {
            width,
            height,
            fps,
            format: None,
        }
    }

    #[test]
    fn default_is_640x480_at_the_highest_rate() {
        let c = choose_mode(&usb(), &WebcamOptions::default()).unwrap();
        assert_eq!(c.mode, m(640, 480, 60, PixelFormat::Mjpeg));
        assert!(c.fallbacks.is_empty());
    }

    #[test]
    fn asked_size_and_rate_are_met_exactly_when_offered() {
        let c = choose_mode(&usb(), &ask(Some(1280), Some(720), Some(30))).unwrap();
        assert_eq!(c.mode, m(1280, 720, 30, PixelFormat::Mjpeg));
        assert!(c.fallbacks.is_empty());
        // At equal size and rate YUYV wins.
        let c = choose_mode(&usb(), &ask(Some(640), Some(480), Some(30))).unwrap();
        assert_eq!(c.mode.format, PixelFormat::Yuyv);
    }

    #[test]
    fn missing_size_or_rate_falls_back_to_the_nearest_and_says_so() {
        let c = choose_mode(&usb(), &ask(Some(1920), Some(1080), Some(50))).unwrap();
        assert_eq!(c.mode, m(1280, 720, 60, PixelFormat::Mjpeg));
        assert_eq!(c.fallbacks.len(), 2, "{:?}", c.fallbacks);
        assert!(c.fallbacks[0].contains("1920x1080"), "{:?}", c.fallbacks);
        assert!(c.fallbacks[1].contains("50 fps"), "{:?}", c.fallbacks);
        // A lone width follows the camera's aspect.
        let c = choose_mode(&usb(), &ask(Some(300), None, None)).unwrap();
        assert_eq!((c.mode.width, c.mode.height), (320, 240));
    }

    #[test]
    fn an_asked_format_the_camera_lacks_is_an_error_naming_what_it_has() {
        let only_yuyv = vec![m(640, 480, 30, PixelFormat::Yuyv)];
        let o = WebcamOptions {
            format: Some(PixelFormat::Mjpeg),
            ..Default::default()
        };
        let e = choose_mode(&only_yuyv, &o).unwrap_err();
        assert!(e.contains("no MJPG") && e.contains("YUYV"), "{e}");
        assert!(choose_mode(&[], &WebcamOptions::default()).is_err());
    }

    #[test]
    fn options_parse_and_print_back() {
        let o = WebcamOptions::parse_query("width=1280&height=720&fps=60&format=MJPEG").unwrap();
        assert_eq!(o.width, Some(1280));
        assert_eq!(o.fps, Some(60));
        assert_eq!(o.format, Some(PixelFormat::Mjpeg));
        assert_eq!(WebcamOptions::parse_query(&o.to_query()).unwrap(), o);
        for bad in [
            "width",
            "width=0",
            "fps=99999",
            "height=-1",
            "zoom=2",
            "format=h264",
        ] {
            assert!(WebcamOptions::parse_query(bad).is_err(), "{bad}");
        }
    }
}
