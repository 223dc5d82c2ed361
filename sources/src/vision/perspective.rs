//! World landmarks in the camera's axes, their picture-plane shape taken from the image
//! landmarks.
//!
//! The landmark model sees a crop around the person and answers in the crop's axes: its world
//! landmarks are the body as a camera looking straight at the person would see it. A person
//! away from the picture's centre is seen along a line of sight tilted from the camera's axis
//! (by up to half the field of view), so the world landmarks come out turned by that angle
//! against the camera, the floor and everything else in the scene. This stage turns them
//! back: the rotation that carries the camera's axis onto the line of sight through the
//! torso's middle (between shoulders and hips). Through the hips, the crop's own centre, did
//! worse where the hips sit at the picture's edge or below it (a person seated at a desk, seen
//! from 0.7 m: the arms' directions 2-3° further off on two of four cameras) and no better on
//! a standing body.
//!
//! It then takes each body point's place across the picture from the image landmarks, which
//! the model reads more closely than the across-picture part of its world landmarks, and keeps
//! only the depth of the world landmarks: each point goes on its own line of sight through
//! its image landmark, at the person's distance plus the point's depth offset from the hips.
//! The person's distance is the one at which the body's across-picture size in the image
//! matches that of the world landmarks, so the result stays in the world landmarks' metres.
//! Both parts need only the picture's size and its field of view, never a calibration.
//!
//! The field of view of a webcam or a clip is not known; [`ASSUMED_DIAGONAL_FOV_DEG`] is a
//! typical one. A wrong guess scales the tilt (and the small perspective of a body's depth),
//! never the across-picture shape the image gives.

use glam::{Quat, Vec2, Vec3};

use super::landmarks::{idx, Landmarks, NUM_LANDMARKS};

/// The diagonal field of view assumed for every picture, degrees: webcams and phones' main
/// cameras span roughly 55° to 80° across the diagonal; 70° sits among them.
pub const ASSUMED_DIAGONAL_FOV_DEG: f32 = 70.0;

/// Segments whose across-picture lengths, summed, give the person's distance: the limbs, the
/// shoulder and hip lines and the torso's sides (the body's larger, steadier parts).
const SIZE_SEGMENTS: [(usize, usize); 12] = [
    (idx::LEFT_SHOULDER, idx::LEFT_ELBOW),
    (idx::LEFT_ELBOW, idx::LEFT_WRIST),
    (idx::RIGHT_SHOULDER, idx::RIGHT_ELBOW),
    (idx::RIGHT_ELBOW, idx::RIGHT_WRIST),
    (idx::LEFT_HIP, idx::LEFT_KNEE),
    (idx::LEFT_KNEE, idx::LEFT_ANKLE),
    (idx::RIGHT_HIP, idx::RIGHT_KNEE),
    (idx::RIGHT_KNEE, idx::RIGHT_ANKLE),
    (idx::LEFT_SHOULDER, idx::RIGHT_SHOULDER),
    (idx::LEFT_HIP, idx::RIGHT_HIP),
    (idx::LEFT_SHOULDER, idx::LEFT_HIP),
    (idx::RIGHT_SHOULDER, idx::RIGHT_HIP),
];

/// No point is put nearer the camera than this share of the person's distance (a hand
/// reaching towards a webcam from close by, read deeper than the person is far).
const NEAREST_SHARE: f32 = 0.25;

/// Visibility from which a landmark counts as seen (the model's own even odds).
const SEEN: f32 = 0.5;

/// A picture's focal length in pixels under the assumed field of view.
fn focal_px(picture: Vec2) -> f32 {
    0.5 * picture.length() / (0.5 * ASSUMED_DIAGONAL_FOV_DEG.to_radians()).tan()
}

/// The person's distance (world landmarks' metres) at which the body's across-picture size
/// seen along `sight` matches the world landmarks' (hip depth `hip_depth`), `None` when there
/// is no size to measure. A point nearer than the hips looks larger: the first guess takes
/// every point at the hips' distance, and two refinements put each at its own depth. Only
/// segments seen at both ends count, by how well they are seen ([`size_weight`]): a hidden
/// wrist guessed far off must not rescale every other bone.
fn distance(lm: &Landmarks, sight: &[Vec2; NUM_LANDMARKS], hip_depth: f32) -> Option<f32> {
    let weight = |a: usize, b: usize| size_weight(lm.visibility(a).min(lm.visibility(b)));
    let world_size: f32 = SIZE_SEGMENTS
        .iter()
        .map(|&(a, b)| weight(a, b) * (lm.world[b] - lm.world[a]).truncate().length())
        .sum();
    let mut distance = f32::INFINITY;
    for _ in 0..3 {
        // Each point's depth relative to the hips' distance (1 on the first guess).
        let scale = |i: usize| {
            let d = 1.0 + (lm.world[i].z - hip_depth) / distance;
            if d.is_finite() {
                d.max(NEAREST_SHARE)
            } else {
                1.0
            }
        };
        let sight_size: f32 = SIZE_SEGMENTS
            .iter()
            .map(|&(a, b)| weight(a, b) * (sight[b] * scale(b) - sight[a] * scale(a)).length())
            .sum();
        distance = world_size / sight_size;
        if !(distance.is_finite() && distance > 0.0) {
            return None;
        }
    }
    Some(distance)
}

/// How much a segment whose ends are seen at `visibility` (the lower of the two) counts
/// towards the person's size: nothing below [`SEEN`], as much as it is seen above.
fn size_weight(visibility: f32) -> f32 {
    if visibility >= SEEN {
        visibility
    } else {
        0.0
    }
}

/// Turns `lm`'s world landmarks into the camera's axes and takes their across-picture shape
/// from its image landmarks (see the module doc). Does nothing when the picture's size is
/// unknown or the landmarks give no size to measure.
pub fn apply(lm: &mut Landmarks) {
    let picture = lm.picture;
    if !(picture.x > 0.0 && picture.y > 0.0 && picture.is_finite()) {
        return;
    }
    let focal = focal_px(picture);
    let centre = picture * 0.5;
    // Each image landmark's line of sight, as (x/z, y/z) in the camera.
    let mut sight = [Vec2::ZERO; NUM_LANDMARKS];
    for (s, p) in sight.iter_mut().zip(&lm.image) {
        *s = (Vec2::new(p.x, p.y) - centre) / focal;
    }
    if !sight.iter().all(|s| s.is_finite()) {
        return;
    }
    let torso = (sight[idx::LEFT_SHOULDER]
        + sight[idx::RIGHT_SHOULDER]
        + sight[idx::LEFT_HIP]
        + sight[idx::RIGHT_HIP])
        * 0.25;
    let turn = Quat::from_rotation_arc(Vec3::Z, torso.extend(1.0).normalize_or_zero());
    for w in lm.world.iter_mut() {
        *w = turn * *w;
    }
    let hip_depth = (lm.world[idx::LEFT_HIP].z + lm.world[idx::RIGHT_HIP].z) * 0.5;
    let Some(distance) = distance(lm, &sight, hip_depth) else {
        return;
    };
    let depth = |w: Vec3| (distance + w.z - hip_depth).max(distance * NEAREST_SHARE);
    let hip_centre = (sight[idx::LEFT_HIP] * depth(lm.world[idx::LEFT_HIP])
        + sight[idx::RIGHT_HIP] * depth(lm.world[idx::RIGHT_HIP]))
        * 0.5;
    for (w, s) in lm.world.iter_mut().zip(&sight) {
        let across = *s * depth(*w) - hip_centre;
        w.x = across.x;
        w.y = across.y;
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use glam::Vec4;

    /// A body of known 3D points (camera axes, metres, hip centre at `at`) seen by a pinhole
    /// camera with the assumed field of view on a 1280×720 picture: the image landmarks, and
    /// world landmarks as the model would give them in the axes of a view of the torso
    /// (hip-centred, turned so that the mean line of sight of shoulders and hips is their z
    /// axis).
    fn seen_from_the_side(at: Vec3) -> (Landmarks, [Vec3; NUM_LANDMARKS]) {
        let picture = Vec2::new(1280.0, 720.0);
        let focal = focal_px(picture);
        let mut body = [Vec3::ZERO; NUM_LANDMARKS];
        for (i, p) in body.iter_mut().enumerate() {
            // Points spread over a body's size and depth, different for every landmark.
            let t = i as f32;
            *p = Vec3::new(
                0.3 * (t * 1.7).sin(),
                0.8 * (t * 0.9).cos(),
                0.25 * (t * 2.3).sin(),
            );
        }
        body[idx::LEFT_HIP] = Vec3::new(0.1, 0.0, 0.02);
        body[idx::RIGHT_HIP] = Vec3::new(-0.1, 0.0, -0.02);
        let mut lm = Landmarks {
            picture,
            ..Landmarks::default()
        };
        let sight = |p: Vec3| Vec2::new(p.x, p.y) / p.z;
        let torso = [
            idx::LEFT_SHOULDER,
            idx::RIGHT_SHOULDER,
            idx::LEFT_HIP,
            idx::RIGHT_HIP,
        ]
        .iter()
        .map(|&i| sight(body[i] + at))
        .sum::<Vec2>()
            * 0.25;
        let to_crop = Quat::from_rotation_arc(torso.extend(1.0).normalize_or_zero(), Vec3::Z);
        for (i, p) in body.iter().enumerate() {
            let c = *p + at;
            let px = Vec2::new(c.x, c.y) / c.z * focal + picture * 0.5;
            lm.image[i] = Vec4::new(px.x, px.y, 0.0, 1.0);
            lm.world[i] = to_crop * *p;
        }
        (lm, body)
    }

    #[test]
    fn a_body_off_centre_comes_back_in_the_cameras_axes() {
        // The hips 1 m left of and 0.6 m above the camera's axis, 3 m away: seen 21° off it.
        let (mut lm, body) = seen_from_the_side(Vec3::new(-1.0, -0.6, 3.0));
        let before = lm.world[idx::LEFT_WRIST] - lm.world[idx::LEFT_ELBOW];
        let want = body[idx::LEFT_WRIST] - body[idx::LEFT_ELBOW];
        assert!(before.angle_between(want).to_degrees() > 5.0);
        apply(&mut lm);
        for &(a, b) in &SIZE_SEGMENTS {
            let got = lm.world[b] - lm.world[a];
            let want = body[b] - body[a];
            assert!(
                got.angle_between(want).to_degrees() < 0.5
                    && (got.length() / want.length() - 1.0).abs() < 0.02,
                "{a}->{b}: {got} against {want}"
            );
        }
        // Hip-centred as before.
        let hips = (lm.world[idx::LEFT_HIP] + lm.world[idx::RIGHT_HIP]) * 0.5;
        assert!(hips.truncate().length() < 1e-4, "{hips}");
    }

    #[test]
    fn the_picture_plane_comes_from_the_image_and_the_depth_from_the_world() {
        let (mut lm, body) = seen_from_the_side(Vec3::new(0.0, 0.0, 3.0));
        // The model misplaces the wrist across the picture in its world landmarks by 10 cm
        // and in depth by nothing; its image landmark is right.
        lm.world[idx::LEFT_WRIST].x += 0.1;
        apply(&mut lm);
        let got = lm.world[idx::LEFT_WRIST] - lm.world[idx::LEFT_ELBOW];
        let want = body[idx::LEFT_WRIST] - body[idx::LEFT_ELBOW];
        assert!(
            got.angle_between(want).to_degrees() < 1.5,
            "{got} against {want}"
        );
        // Depth is the world landmarks': the wrist read 20 cm nearer comes out 20 cm nearer
        // (along the torso's line of sight, 5° off the camera's axis here).
        let (mut plain, _) = seen_from_the_side(Vec3::new(0.0, 0.0, 3.0));
        let mut deep = plain;
        deep.world[idx::LEFT_WRIST].z -= 0.2;
        apply(&mut plain);
        apply(&mut deep);
        let nearer = plain.world[idx::LEFT_WRIST].z - deep.world[idx::LEFT_WRIST].z;
        assert!((nearer - 0.2).abs() < 0.002, "{nearer}");
    }

    #[test]
    fn a_hidden_joint_guessed_far_off_moves_no_other_bone() {
        // The wrist hidden: guessed where it is, or 300 px and 40 cm off.
        let (mut lm, _) = seen_from_the_side(Vec3::new(-1.0, -0.6, 3.0));
        lm.image[idx::LEFT_WRIST].w = 0.05;
        let mut misread = lm;
        misread.image[idx::LEFT_WRIST].y -= 300.0;
        misread.world[idx::LEFT_WRIST] += Vec3::new(0.0, -0.3, -0.3);
        apply(&mut lm);
        apply(&mut misread);
        for &(a, b) in SIZE_SEGMENTS.iter().filter(|&&(_, b)| b != idx::LEFT_WRIST) {
            let (got, want) = (
                misread.world[b] - misread.world[a],
                lm.world[b] - lm.world[a],
            );
            assert!(
                got.abs_diff_eq(want, 1e-5),
                "{a}->{b}: {got} against {want}"
            );
        }
    }

    #[test]
    fn without_the_pictures_size_nothing_changes() {
        let (mut lm, _) = seen_from_the_side(Vec3::new(-1.0, -0.6, 3.0));
        lm.picture = Vec2::ZERO;
        let before = lm;
        apply(&mut lm);
        assert_eq!(lm, before);
        // Nor when every point sits on one pixel (no size to measure).
        let (mut flat, _) = seen_from_the_side(Vec3::new(0.0, 0.0, 3.0));
        for p in flat.image.iter_mut() {
            *p = Vec4::new(640.0, 360.0, 0.0, 1.0);
        }
        let world = flat.world;
        apply(&mut flat);
        assert!(flat
            .world
            .iter()
            .zip(&world)
            .all(|(a, b)| a.is_finite() && b.is_finite()));
    }
}
