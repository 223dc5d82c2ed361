//! The requests that change the server (`calibrate`, `set_performer`, `set_mapping`), carried
//! out the same way for a local client session and for a request another node forwarded
//! (`cluster::control`): the connection's right to change the server is checked before.

use rigcast_engine::inbox::Busy;
use rigcast_protocol::control::{ClientMessage, ErrorCode};
use rigcast_protocol::ServerMessage;
use rigcast_retarget::Skeleton;

use crate::state::Changes;
use rigcast_engine::tick::EngineCommand;

/// Carries out a request that changes the server (the connection's right to it already
/// checked, here or by the node that forwarded it).
pub fn apply_change(state: &Changes, msg: ClientMessage) -> ServerMessage {
    match msg {
        ClientMessage::Calibrate {
            subject,
            pose,
            delay_secs,
        } => match crate::calibration::start(
            &state.subjects(),
            &state.events,
            subject,
            pose,
            delay_secs,
        ) {
            Ok(()) => ServerMessage::Ack {
                request: "calibrate".into(),
                subject,
            },
            Err(refusal) => ServerMessage::error(refusal.code(), refusal.to_string()),
        },
        ClientMessage::SetPerformer { subject, foot_lock } => {
            set_performer(state, subject, foot_lock)
        }
        ClientMessage::SetMapping { subject, overrides } => set_mapping(state, subject, overrides),
        other => ServerMessage::error(
            ErrorCode::Unsupported,
            format!("{} does not change the server", type_name(&other)),
        ),
    }
}

/// `set_performer`: switches a target's foot lock (a re-map, off the tick).
fn set_performer(state: &Changes, subject: u32, foot_lock: Option<bool>) -> ServerMessage {
    let Some(target) = state.subject(subject) else {
        return ServerMessage::error(
            ErrorCode::UnknownSubject,
            format!("unknown subject id {subject}"),
        );
    };
    if !target.is_target() {
        return ServerMessage::error(
            ErrorCode::Unsupported,
            format!("subject {subject} is a source; set_performer applies to target subjects"),
        );
    }
    let cmd = EngineCommand::SetPerformer { subject, foot_lock };
    send_command(state, cmd, "set_performer", subject)
}

/// `set_mapping`: overrides checked against the skeletons now, applied by the mapper.
fn set_mapping(
    state: &Changes,
    subject: u32,
    overrides: std::collections::BTreeMap<String, Option<String>>,
) -> ServerMessage {
    let Some(target) = state.subject(subject) else {
        return ServerMessage::error(
            ErrorCode::UnknownSubject,
            format!("unknown subject id {subject}"),
        );
    };
    if let Err(message) = check_overrides(state, &target, &overrides) {
        return ServerMessage::error(ErrorCode::Unsupported, message);
    }
    let cmd = EngineCommand::SetMapping { subject, overrides };
    send_command(state, cmd, "set_mapping", subject)
}

/// Hands a command to the engine and answers `ack`, or an error when it cannot take it now.
fn send_command(state: &Changes, cmd: EngineCommand, request: &str, subject: u32) -> ServerMessage {
    match state.inbox.request(cmd) {
        Ok(()) => ServerMessage::Ack {
            request: request.into(),
            subject,
        },
        Err(Busy) => ServerMessage::error(ErrorCode::Internal, "engine is busy; retry"),
    }
}

/// Checks `set_mapping` overrides against the target's and its sources' skeletons, so a typo
/// is answered at once instead of failing later in the mapper.
fn check_overrides(
    state: &Changes,
    target: &rigcast_engine::subject::Subject,
    overrides: &std::collections::BTreeMap<String, Option<String>>,
) -> Result<(), String> {
    if !target.is_target() {
        return Err(format!(
            "subject {} is a source; set_mapping applies to target subjects",
            target.id
        ));
    }
    let tsk = target.skeleton();
    let sources: Vec<_> = target
        .inputs
        .iter()
        .filter_map(|id| state.subject(*id).map(|s| s.skeleton()))
        .collect();
    let refs: Vec<&rigcast_retarget::Skeleton> = sources.iter().map(|s| &**s).collect();
    for (t, s) in overrides {
        if tsk.bone(t).is_none() {
            return Err(format!("target subject {} has no bone {t:?}", target.id));
        }
        if let Some(s) = s {
            if find_source_bone(&refs, s).is_none() {
                return Err(format!(
                    "no source of target subject {} has a bone {s:?}",
                    target.id
                ));
            }
        }
    }
    Ok(())
}

/// The `type` of a message, for error texts.
pub(crate) fn type_name(msg: &ClientMessage) -> &'static str {
    match msg {
        ClientMessage::Subscribe { .. } => "subscribe",
        ClientMessage::Ping { .. } => "ping",
        ClientMessage::SetProtocol { .. } => "set_protocol",
        ClientMessage::SetMapping { .. } => "set_mapping",
        ClientMessage::Calibrate { .. } => "calibrate",
        ClientMessage::SetPerformer { .. } => "set_performer",
    }
}

/// The first source skeleton (in input order) with a bone of that name.
pub fn find_source_bone(
    sources: &[&Skeleton],
    name: &str,
) -> Option<(u16, rigcast_retarget::BoneId)> {
    sources
        .iter()
        .enumerate()
        .find_map(|(i, s)| s.bone(name).map(|b| (i as u16, b)))
}
