//! `rigcast calibrate [--url URL] [--subject NAME|ID] [--pose t|n] [--delay SECS]`: calibrate a
//! running server's serial IMU suit. The performer holds the pose; after the countdown each
//! sensor's reading becomes its mounting offset.
//!
//! ```text
//!  connect ─▶ hello + source_status ─▶ pick the subject (named, or the only serial source)
//!    ─▶ send calibrate{subject, pose, delay_secs} ─▶ ack | error (exit 1)
//!    ─▶ countdown "3 2 1" while the server waits ─▶ source_status detail
//!         "calibrated (T-pose)" (exit 0) | "calibration failed: …" (exit 1)
//! ```

use std::io::Write;
use std::time::Duration;

use anyhow::{bail, Context};
use clap::{Args, ValueEnum};
use futures_util::{SinkExt, StreamExt};
use rigcast_protocol::control::{
    CalibrationPose, ClientMessage, SourceHealth, SubjectInfo, MAX_CALIBRATION_DELAY_SECS,
};
use rigcast_protocol::{ServerMessage, SourceKind};
use tokio::time::Instant;
use tokio_tungstenite::tungstenite::Message;

use crate::calibration::{FAILURE_PREFIX, PENDING_PREFIX, SUCCESS_PREFIX};

/// Options of `rigcast calibrate`.
#[derive(Debug, Args)]
pub struct CalibrateArgs {
    /// Server stream URL.
    #[arg(long, default_value = "ws://127.0.0.1:8717/v1/stream")]
    pub url: String,
    /// The source to calibrate, by subject name or id (default: the only serial IMU source).
    #[arg(long)]
    pub subject: Option<String>,
    /// The pose the performer holds: `t` (arms out sideways) or `n` (arms down).
    #[arg(long, value_enum, default_value_t = PoseArg::T)]
    pub pose: PoseArg,
    /// Seconds to get into the pose before the sensors are read.
    #[arg(long, default_value_t = 3.0)]
    pub delay: f32,
    /// The server's control token (default: read from the token file).
    #[arg(long)]
    pub token: Option<String>,
    /// The token file (default `$XDG_CONFIG_HOME/rigcast/token`).
    #[arg(long, value_name = "PATH")]
    pub token_file: Option<std::path::PathBuf>,
}

/// `--pose`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum PoseArg {
    /// T-pose.
    T,
    /// N-pose.
    N,
}

impl PoseArg {
    fn wire(self) -> CalibrationPose {
        match self {
            PoseArg::T => CalibrationPose::T,
            PoseArg::N => CalibrationPose::N,
        }
    }

    fn instruction(self) -> &'static str {
        match self {
            PoseArg::T => "hold a T-pose (stand straight, arms out sideways, palms down)",
            PoseArg::N => "hold an N-pose (stand straight, arms down along the body)",
        }
    }
}

/// How long to wait for the server's greeting and for each answer.
const ANSWER_TIMEOUT: Duration = Duration::from_secs(5);

type Socket =
    tokio_tungstenite::WebSocketStream<tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>>;

/// Runs the command; `Ok` only when the server reports the source calibrated.
pub async fn run(args: CalibrateArgs) -> anyhow::Result<()> {
    if !(args.delay.is_finite() && (0.0..=MAX_CALIBRATION_DELAY_SECS).contains(&args.delay)) {
        bail!(
            "--delay must be between 0 and {MAX_CALIBRATION_DELAY_SECS} seconds, got {}",
            args.delay
        );
    }
    let mut ws = connect(&args).await?;
    let (subjects, sources) = greeting(&mut ws).await?;
    let (id, name) = pick_subject(&subjects, &sources, args.subject.as_deref())?;
    let request = ClientMessage::Calibrate {
        subject: id,
        pose: args.pose.wire(),
        delay_secs: args.delay,
    };
    let text = serde_json::to_string(&request).context("encoding the request")?;
    ws.send(Message::text(text))
        .await
        .context("sending the calibrate request")?;
    let who = Named { id, name: &name };
    await_outcome(&mut ws, who, &args).await
}

/// Opens the stream with the control token.
async fn connect(args: &CalibrateArgs) -> anyhow::Result<Socket> {
    let token = crate::token::client_token(args.token.as_deref(), args.token_file.as_deref())?;
    let request = crate::token::authorized_request(&args.url, token.as_ref())?;
    let connect = tokio_tungstenite::connect_async(request);
    let (ws, _) = tokio::time::timeout(ANSWER_TIMEOUT, connect)
        .await
        .with_context(|| format!("cannot connect to {}: timed out", args.url))?
        .with_context(|| {
            format!(
                "cannot connect to {} (is `rigcast serve` running?)",
                args.url
            )
        })?;
    Ok(ws)
}

/// The greeting: hello, skeletons, mappings, then the first source_status.
async fn greeting(ws: &mut Socket) -> anyhow::Result<(Vec<SubjectInfo>, Vec<SourceHealth>)> {
    let mut subjects: Option<Vec<SubjectInfo>> = None;
    let sources: Vec<SourceHealth> = loop {
        match next_message(ws, Instant::now() + ANSWER_TIMEOUT).await? {
            ServerMessage::Hello { subjects: s, .. } => subjects = Some(s),
            ServerMessage::SourceStatus { sources, .. } => break sources,
            _ => {}
        }
    };
    let subjects = subjects.context("the server sent no hello")?;
    Ok((subjects, sources))
}

/// The subject being calibrated, as the messages name it.
#[derive(Clone, Copy)]
struct Named<'a> {
    id: u32,
    name: &'a str,
}

/// The "3 2 1" printed while the server waits for the performer.
struct Countdown {
    left: u32,
    next_tick: Instant,
}

impl Countdown {
    fn new(capture_at: Instant, delay_secs: f32) -> Countdown {
        let left = delay_secs.ceil() as u32;
        Countdown {
            left,
            next_tick: capture_at - Duration::from_secs(u64::from(left)),
        }
    }

    /// Prints the next number (and ends the line after the last).
    fn tick(&mut self) {
        print!(" {}", self.left);
        if self.left == 1 {
            println!();
        }
        // Progress only: the capture goes on if stdout is closed.
        let _ = std::io::stdout().flush();
        self.left -= 1;
        self.next_tick += Duration::from_secs(1);
    }

    /// Ends a line the countdown left open.
    fn end_line(&self) {
        if self.left > 0 {
            println!();
        }
    }
}

/// Waits for the server's answer and the capture's outcome, counting down meanwhile.
///
/// Statuses published before the request may still be queued; the outcome is the first
/// final text after the server's "calibrating …" one.
async fn await_outcome(
    ws: &mut Socket,
    who: Named<'_>,
    args: &CalibrateArgs,
) -> anyhow::Result<()> {
    let Named { id, name } = who;
    let mut seen_pending = false;
    let mut acked = false;
    let capture_at = Instant::now() + Duration::from_secs_f32(args.delay);
    let mut countdown = Countdown::new(capture_at, args.delay);
    let give_up = capture_at + ANSWER_TIMEOUT;
    loop {
        let msg = tokio::select! {
            m = next_message(ws, give_up) => m?,
            _ = tokio::time::sleep_until(countdown.next_tick), if acked && countdown.left > 0 => {
                countdown.tick();
                continue;
            }
        };
        match msg {
            ServerMessage::Error { code, message, .. } if !acked => {
                bail!(
                    "the server refused to calibrate subject {id} ({name}): {message} [{}]",
                    code.as_str()
                )
            }
            ServerMessage::Ack { request, subject } if request == "calibrate" && subject == id => {
                acked = true;
                announce(who, args.pose, countdown.left);
            }
            ServerMessage::SourceStatus { sources, .. } => {
                let Some(detail) = sources.iter().find(|s| s.subject == id).map(|s| &s.detail)
                else {
                    continue;
                };
                if detail.starts_with(PENDING_PREFIX) {
                    seen_pending = true;
                } else if seen_pending && detail.starts_with(SUCCESS_PREFIX) {
                    countdown.end_line();
                    println!("{name} (subject {id}): {detail}; sensor offsets captured");
                    return Ok(());
                } else if seen_pending && detail.starts_with(FAILURE_PREFIX) {
                    countdown.end_line();
                    bail!("{name} (subject {id}): {detail}");
                }
            }
            _ => {}
        }
    }
}

/// Tells the performer what to hold, once the server took the request.
fn announce(who: Named<'_>, pose: PoseArg, countdown_left: u32) {
    let Named { id, name } = who;
    let what = pose.instruction();
    if countdown_left == 0 {
        println!("calibrating {name} (subject {id}): {what}; capturing now");
    } else {
        print!("calibrating {name} (subject {id}): {what}…");
        // Progress only, as in the countdown.
        let _ = std::io::stdout().flush();
    }
}

/// The subject to calibrate: `wanted` by name or id, else the only serial source.
fn pick_subject(
    subjects: &[SubjectInfo],
    sources: &[SourceHealth],
    wanted: Option<&str>,
) -> anyhow::Result<(u32, String)> {
    let list = || {
        subjects
            .iter()
            .map(|s| {
                let kind = sources
                    .iter()
                    .find(|h| h.subject == s.id)
                    .map_or("target".to_string(), |h| h.kind.to_string());
                format!("{} {:?} ({kind})", s.id, s.name)
            })
            .collect::<Vec<_>>()
            .join(", ")
    };
    if let Some(w) = wanted {
        // Names first: a subject may well be called "2".
        let found = subjects.iter().find(|s| s.name == w).or_else(|| {
            w.parse::<u32>()
                .ok()
                .and_then(|id| subjects.iter().find(|s| s.id == id))
        });
        return match found {
            Some(s) => Ok((s.id, s.name.clone())),
            None => bail!("no subject named or numbered {w:?}; subjects: {}", list()),
        };
    }
    let serial: Vec<&SourceHealth> = sources
        .iter()
        .filter(|h| h.kind == SourceKind::Serial)
        .collect();
    match serial.as_slice() {
        [one] => {
            let name = subjects
                .iter()
                .find(|s| s.id == one.subject)
                .map_or_else(|| format!("subject {}", one.subject), |s| s.name.clone());
            Ok((one.subject, name))
        }
        [] => bail!(
            "no calibratable source on this server (only serial IMU suits can be calibrated); subjects: {}",
            list()
        ),
        _ => bail!(
            "several serial IMU sources; choose one with --subject NAME|ID: {}",
            list()
        ),
    }
}

/// The next control message (binary frames are skipped), or an error at `deadline`.
async fn next_message<S>(
    ws: &mut tokio_tungstenite::WebSocketStream<S>,
    deadline: Instant,
) -> anyhow::Result<ServerMessage>
where
    S: tokio::io::AsyncRead + tokio::io::AsyncWrite + Unpin,
{
    loop {
        let msg = tokio::time::timeout_at(deadline, ws.next())
            .await
            .context("timed out waiting for the server")?;
        match msg {
            None => bail!("the server closed the connection"),
            Some(Err(e)) => bail!("connection error: {e}"),
            Some(Ok(Message::Text(text))) => {
                // Messages from newer servers that this build does not know are skipped.
                if let Ok(m) = serde_json::from_str::<ServerMessage>(text.as_str()) {
                    return Ok(m);
                }
            }
            Some(Ok(Message::Close(_))) => bail!("the server closed the connection"),
            Some(Ok(_)) => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rigcast_protocol::control::SubjectKind;
    use rigcast_protocol::SourceState;

    fn info(id: u32, name: &str) -> SubjectInfo {
        SubjectInfo {
            id,
            name: name.into(),
            kind: SubjectKind::Source,
            source: None,
            num_bones: 1,
            fingerprint: "0".repeat(16),
            model: None,
        }
    }

    fn health(id: u32, kind: SourceKind) -> SourceHealth {
        SourceHealth {
            subject: id,
            kind,
            state: SourceState::Live,
            input_fps: 0.0,
            latency_ms: 0.0,
            frames: 0,
            dropped: 0,
            detail: String::new(),
            camera: None,
        }
    }

    #[test]
    fn picks_the_only_serial_source_or_the_named_one() {
        let subjects = [info(0, "walk"), info(1, "suit"), info(2, "7")];
        let sources = [
            health(0, SourceKind::Replay),
            health(1, SourceKind::Serial),
            health(2, SourceKind::Vmc),
        ];
        assert_eq!(pick_subject(&subjects, &sources, None).unwrap().0, 1);
        assert_eq!(
            pick_subject(&subjects, &sources, Some("walk")).unwrap().0,
            0
        );
        assert_eq!(pick_subject(&subjects, &sources, Some("1")).unwrap().0, 1);
        assert_eq!(pick_subject(&subjects, &sources, Some("7")).unwrap().0, 2);
        let e = pick_subject(&subjects, &sources, Some("nope"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("\"nope\"") && e.contains("1 \"suit\" (serial)"),
            "{e}"
        );
        let e = pick_subject(&subjects[..1], &sources[..1], None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("no calibratable source"), "{e}");
        let two = [health(0, SourceKind::Serial), health(1, SourceKind::Serial)];
        let e = pick_subject(&subjects, &two, None).unwrap_err().to_string();
        assert!(e.contains("--subject"), "{e}");
    }
}
