//! `describe`: what `rigcast info <file>` prints about an animation file.

use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use rigcast_retarget::{Clip, Skeleton};

use crate::bvh::{read_bvh, BvhReadOptions};
use crate::error::SourceError;
use crate::files::{extension, read_file, stem, LoadOptions};
use crate::gltf::{read_gltf, AnimationInfo, GltfReadOptions};
use crate::recording::{clip_from_recording, read_recording};
use crate::stature::stature;

/// A summary of one file's skeleton and animation.
#[derive(Debug, Clone)]
pub struct FileInfo {
    /// The file.
    pub path: PathBuf,
    /// Format name ("BVH", "glTF", "GLB", "VRM", "rigcast recording").
    pub format: &'static str,
    /// The skeleton.
    pub skeleton: Arc<Skeleton>,
    /// Number of bones (BVH End Sites included, as `<parent>_end` leaves).
    pub num_bones: usize,
    /// Standing height of the figure along its own up axis, metres.
    pub height_m: f32,
    /// True when the rest pose is not a posture (bones folded along one line) and the height
    /// was measured on the first animation frame instead.
    pub height_from_first_frame: bool,
    /// Frame rate of the loaded animation (None without frames).
    pub fps: Option<f64>,
    /// Frames of the loaded animation.
    pub num_frames: usize,
    /// Duration of the loaded animation, seconds (frames × frame time).
    pub duration_secs: f64,
    /// All animations in the file (one entry for BVH and recordings).
    pub animations: Vec<AnimationInfo>,
    /// BVH only: metres per file unit applied, whether it was guessed, and how sure the guess
    /// is (0..1; 1 when given).
    pub bvh_scale: Option<(f32, bool, f32)>,
    /// VRM only: humanoid role → bone name.
    pub vrm_roles: Option<BTreeMap<String, String>>,
    /// Recordings only: (subjects, frames, raw packets, ended cleanly).
    pub recording: Option<(usize, usize, usize, bool)>,
}

impl FileInfo {
    /// The bone hierarchy as an indented list, one bone per line.
    pub fn bone_tree(&self) -> String {
        let mut out = String::new();
        for b in self.skeleton.bone_ids() {
            let depth = self.skeleton.depth(b);
            out.push_str(&"  ".repeat(depth));
            out.push_str(self.skeleton.name(b));
            out.push('\n');
        }
        out
    }
}

impl fmt::Display for FileInfo {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "file:      {}", self.path.display())?;
        writeln!(f, "format:    {}", self.format)?;
        writeln!(f, "bones:     {}", self.num_bones)?;
        let note = if self.height_from_first_frame {
            " (first frame; the rest pose is not a posture)"
        } else {
            ""
        };
        writeln!(f, "height:    {:.3} m{note}", self.height_m)?;
        match self.bvh_scale {
            Some((scale, false, _)) => writeln!(f, "scale:     {scale} m per unit (given)")?,
            Some((scale, true, sure)) => writeln!(
                f,
                "scale:     {scale} m per unit (guessed from the height, {:.0} % sure{})",
                sure * 100.0,
                if sure < 0.8 {
                    "; the unit may be wrong: `--unit` gives it"
                } else {
                    ""
                }
            )?,
            None => {}
        }
        match self.fps {
            Some(fps) => writeln!(
                f,
                "frames:    {} at {:.3} fps, {:.3} s",
                self.num_frames, fps, self.duration_secs
            )?,
            None => writeln!(f, "frames:    none")?,
        }
        if let Some((subjects, frames, raw, clean)) = self.recording {
            writeln!(
                f,
                "recording: {subjects} subjects, {frames} frames, {raw} raw packets{}",
                if clean { "" } else { ", truncated" }
            )?;
        }
        if !self.animations.is_empty() {
            writeln!(f, "animations:")?;
            for a in &self.animations {
                writeln!(f, "  {} ({:.3} s)", a.name, a.duration_secs)?;
            }
        }
        if let Some(roles) = &self.vrm_roles {
            writeln!(f, "VRM humanoid bones: {}", roles.len())?;
        }
        writeln!(f, "hierarchy:")?;
        for line in self.bone_tree().lines() {
            writeln!(f, "  {line}")?;
        }
        Ok(())
    }
}

/// Standing height along the figure's own up axis, at rest or on the first frame when the
/// rest is not a posture (see [`stature`]).
fn height_of(clip: &Clip) -> (f32, bool) {
    let s = stature(&clip.skeleton, clip.poses.first());
    (s.height, s.from_first_frame)
}

/// Reads `path` and summarises it (see [`FileInfo`]); a BVH's unit is guessed.
pub fn describe(path: &Path) -> Result<FileInfo, SourceError> {
    describe_with(path, &LoadOptions::default())
}

/// [`describe`] with load options: a BVH read at `opts.bvh_scale` when given (the unit is then
/// reported as given, not guessed).
pub fn describe_with(path: &Path, opts: &LoadOptions) -> Result<FileInfo, SourceError> {
    describe_inner(path, opts).map_err(|e| e.in_file(path))
}

fn describe_inner(path: &Path, opts: &LoadOptions) -> Result<FileInfo, SourceError> {
    let ext = extension(path);
    let bytes = read_file(path)?;
    let read = match ext.as_str() {
        "bvh" => read_bvh_info(&bytes, path, opts)?,
        "gltf" | "glb" | "vrm" => read_gltf_info(&bytes, path, &ext)?,
        "rcr" => read_recording_info(&bytes, path)?,
        _ => {
            return Err(SourceError::UnsupportedExtension {
                extension: ext,
                expected: ".bvh, .gltf, .glb, .vrm, .rcr",
            })
        }
    };
    let clip = read.clip;
    let (height_m, height_from_first_frame) = height_of(&clip);
    let has_frames = clip.num_frames() > 0;
    Ok(FileInfo {
        path: path.to_path_buf(),
        format: read.format,
        num_bones: clip.skeleton.num_bones(),
        skeleton: clip.skeleton.clone(),
        height_m,
        height_from_first_frame,
        fps: has_frames.then(|| clip.fps()),
        num_frames: clip.num_frames(),
        duration_secs: clip.duration_secs(),
        animations: read.animations,
        bvh_scale: read.bvh_scale,
        vrm_roles: read.vrm_roles,
        recording: read.recording,
    })
}

/// What one format's reader gives [`FileInfo`]: the clip, its animations, and the facts only
/// that format has.
struct FormatRead {
    format: &'static str,
    clip: Clip,
    animations: Vec<AnimationInfo>,
    bvh_scale: Option<(f32, bool, f32)>,
    vrm_roles: Option<BTreeMap<String, String>>,
    recording: Option<(usize, usize, usize, bool)>,
}

/// The one animation a BVH or a recording holds: the clip itself.
fn only_animation(clip: &Clip) -> Vec<AnimationInfo> {
    vec![AnimationInfo {
        name: clip.name.clone(),
        duration_secs: clip.duration_secs(),
    }]
}

fn read_bvh_info(bytes: &[u8], path: &Path, opts: &LoadOptions) -> Result<FormatRead, SourceError> {
    let bvh_opts = BvhReadOptions {
        scale: opts.bvh_scale,
    };
    let r = read_bvh(bytes, &stem(path), &bvh_opts)?;
    Ok(FormatRead {
        format: "BVH",
        animations: only_animation(&r.clip),
        bvh_scale: Some((r.scale, r.scale_guessed, r.scale_confidence)),
        clip: r.clip,
        vrm_roles: None,
        recording: None,
    })
}

fn read_gltf_info(bytes: &[u8], path: &Path, ext: &str) -> Result<FormatRead, SourceError> {
    let r = read_gltf(
        bytes,
        path.parent(),
        &stem(path),
        &GltfReadOptions::default(),
    )?;
    let format = match ext {
        "gltf" => "glTF",
        "glb" => "GLB",
        _ => "VRM",
    };
    Ok(FormatRead {
        format,
        clip: r.clip,
        animations: r.animations,
        vrm_roles: r.vrm_roles,
        bvh_scale: None,
        recording: None,
    })
}

fn read_recording_info(bytes: &[u8], path: &Path) -> Result<FormatRead, SourceError> {
    let rec = read_recording(bytes)?;
    let clip = clip_from_recording(&rec, &stem(path))?;
    Ok(FormatRead {
        format: "rigcast recording",
        animations: only_animation(&clip),
        recording: Some((
            rec.skeletons.len(),
            rec.frames.len(),
            rec.raw.len(),
            rec.ended_cleanly,
        )),
        clip,
        bvh_scale: None,
        vrm_roles: None,
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use glam::{Quat, Vec3};
    use rigcast_retarget::{RawSkeleton, Transform};

    /// A rest layout with every bone along +X (not a posture): the height must come from the
    /// first frame, where the root is turned so the chain stands up.
    #[test]
    fn degenerate_rest_uses_first_frame_height() {
        let mut raw = RawSkeleton::default();
        let mut parent = raw.add("root", None, Transform::IDENTITY);
        for k in 0..4 {
            parent = raw.add(
                format!("b{k}"),
                Some(parent),
                Transform::from_translation(Vec3::X * 0.4),
            );
        }
        let s = Arc::new(Skeleton::build(&raw).unwrap());
        let mut pose = s.rest_pose();
        pose.rotations[0] = Quat::from_rotation_z(std::f32::consts::FRAC_PI_2);
        let clip = Clip::new("c", s.clone(), vec![pose], 0.1).unwrap();
        let (h, from_frame) = height_of(&clip);
        assert!(from_frame);
        assert!((h - 1.6).abs() < 1e-5, "{h}");
        // Without frames there is nothing better than the (flat) rest.
        let empty = Clip::new("c", s, vec![], 0.1).unwrap();
        assert_eq!(height_of(&empty), (0.0, false));
    }
}
