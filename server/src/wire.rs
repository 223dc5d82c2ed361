//! The transport's edge: engine events and the state clients are told about, as protocol
//! messages. The one place that turns the server's own types into [`ServerMessage`]s for
//! every client (`clients`) and for the cluster's bucket entries (`cluster::publish`).

use rigcast_protocol::control::{BoneInfo, ErrorCode};
use rigcast_protocol::{ServerMessage, PROTOCOL_VERSION};

use std::sync::Arc;

use rigcast_engine::events::Event;
use rigcast_engine::reports::{FootplantReport, HealthReport, MappingReport};
use rigcast_engine::subject::{Subject, SubjectShape};

/// The protocol message of `event`.
pub fn message(event: &Event) -> ServerMessage {
    match event {
        Event::SubjectsChanged(shapes) => ServerMessage::SubjectsChanged {
            subjects: shapes.iter().map(|s| s.info.clone()).collect(),
        },
        Event::Skeleton(shape) => skeleton(shape),
        Event::Mapping(report) => mapping(report),
        Event::Footplants(report) => footplants(report),
        Event::SourceStatus(report) => source_status(report),
        Event::SubjectFaulted { subject, name, why } => ServerMessage::Error {
            code: ErrorCode::SubjectFaulted,
            message: format!("subject {subject} ({name}): {why}"),
            subject: Some(*subject),
        },
    }
}

/// The `skeleton` message of a subject's shape.
pub fn skeleton(shape: &SubjectShape) -> ServerMessage {
    ServerMessage::Skeleton {
        subject: shape.info.id,
        name: shape.info.name.clone(),
        fingerprint: shape.info.fingerprint.clone(),
        bones: bones(shape),
    }
}

/// A shape's bones as the `skeleton` message lists them.
pub fn bones(shape: &SubjectShape) -> Vec<BoneInfo> {
    let skeleton = &shape.skeleton;
    skeleton
        .bone_ids()
        .map(|b| {
            let rest = skeleton.rest()[b.index()];
            BoneInfo {
                name: skeleton.name(b).to_string(),
                parent: skeleton.parent(b).map(|p| p.0 as u32),
                rest_translation: rest.translation.to_array(),
                rest_rotation: rest.rotation.to_array(),
                translated: shape.translated.binary_search(&(b.0)).is_ok(),
            }
        })
        .collect()
}

/// The `mapping` message of a target's mapping.
pub fn mapping(report: &MappingReport) -> ServerMessage {
    ServerMessage::Mapping {
        subject: report.subject,
        source_subject: report.source_subject,
        entries: report.entries.clone(),
        warnings: report.warnings.clone(),
    }
}

/// The `footplants` message of a target's planted feet.
pub fn footplants(report: &FootplantReport) -> ServerMessage {
    ServerMessage::Footplants {
        subject: report.subject,
        seq: report.seq,
        feet: report.feet.clone(),
    }
}

/// The `source_status` message of a health report.
pub fn source_status(report: &HealthReport) -> ServerMessage {
    ServerMessage::SourceStatus {
        sources: report.sources.clone(),
        targets: report.targets.clone(),
    }
}

/// The `hello` message.
pub fn hello(tick_hz: f64, subjects: &[Arc<Subject>]) -> ServerMessage {
    ServerMessage::Hello {
        protocol_version: PROTOCOL_VERSION,
        protocol_versions: rigcast_protocol::PROTOCOL_VERSIONS.to_vec(),
        server_version: env!("CARGO_PKG_VERSION").to_string(),
        tick_hz,
        subjects: subjects.iter().map(|s| s.info()).collect(),
    }
}

/// The state that control messages describe, as those messages: every subject's skeleton,
/// every built mapping, every target's planted feet, the sources' health. Sent on connect and
/// after a control-queue lag.
pub fn state_messages(subjects: &[Arc<Subject>]) -> Vec<ServerMessage> {
    let mut out: Vec<ServerMessage> = subjects.iter().map(|s| skeleton(&s.shape())).collect();
    out.extend(
        subjects
            .iter()
            .filter_map(|s| s.mapping().map(|m| mapping(&m))),
    );
    out.extend(
        subjects
            .iter()
            .filter_map(|s| s.footplants().map(|f| footplants(&f))),
    );
    out.push(source_status(&rigcast_engine::subject::health_report(
        subjects,
        std::time::Instant::now(),
    )));
    out
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use rigcast_engine::subject::Subject;

    /// A subject's `skeleton` message, read back the way a relaying node reads it, is the
    /// same skeleton (same fingerprint), and marks exactly the shape's translated bones.
    #[test]
    fn a_skeleton_event_carries_the_skeleton_and_its_translated_bones() {
        let sk = Arc::new(rigcast_engine::builtin::mannequin().unwrap());
        let (target, _tx) = Subject::with_kind(
            3,
            "mannequin".into(),
            sk.clone(),
            None,
            vec![0],
            rigcast_engine::settings::VmcBoneNames::default(),
        );
        let event = Event::skeleton(&target);
        let text = message(&event).to_json();
        let Ok(ServerMessage::Skeleton {
            subject,
            name,
            fingerprint,
            bones,
        }) = serde_json::from_str::<ServerMessage>(&text)
        else {
            panic!("not a skeleton message: {text}");
        };
        assert_eq!((subject, name.as_str()), (3, "mannequin"));
        assert_eq!(fingerprint, sk.fingerprint_hex());
        let back = crate::skeleton_wire::skeleton_from_bones(&bones).unwrap();
        assert_eq!(back.fingerprint(), sk.fingerprint());
        let marked: Vec<u16> = (0..bones.len() as u16)
            .filter(|&i| bones[i as usize].translated)
            .collect();
        assert!(!marked.is_empty());
        assert_eq!(marked, target.shape().translated);
    }

    /// A fault reaches clients as the `error` it always was: code, subject, and why.
    #[test]
    fn a_fault_event_is_an_error_about_its_subject() {
        let event = Event::SubjectFaulted {
            subject: 2,
            name: "robot".into(),
            why: "stopped: boom".into(),
        };
        assert_eq!(
            message(&event),
            ServerMessage::Error {
                code: ErrorCode::SubjectFaulted,
                message: "subject 2 (robot): stopped: boom".into(),
                subject: Some(2),
            }
        );
    }
}
