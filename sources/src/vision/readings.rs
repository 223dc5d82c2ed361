//! How two landmark readings compare: one body read twice, one face, a body that continues
//! another one frame later (its place, its step, its size), a reading within another's body, a
//! torso turned over, an upside-down twin. The tracker's identity decisions (`tracker`) rest
//! on these; they are geometry on the readings alone, with no state.

use glam::Vec2;

use super::detector::Detection;
use super::landmarks::{idx, Landmarks, NUM_LANDMARKS};
use super::model::Disc;
use super::sides::mirror_index;

/// The disc covering `lm`'s head: around the nose, out past the ears (at least half the
/// shoulder width, for a head seen from the side); None when no head is seen.
pub(super) fn face_disc(lm: &Landmarks) -> Option<Disc> {
    let point = |i: usize| Vec2::new(lm.image[i].x, lm.image[i].y);
    let ears = point(idx::LEFT_EAR).distance(point(idx::RIGHT_EAR));
    let shoulders = point(idx::LEFT_SHOULDER).distance(point(idx::RIGHT_SHOULDER));
    let radius = (0.75 * ears).max(FACE_RADIUS * shoulders);
    (radius > 1.0).then_some(Disc {
        center: point(idx::NOSE),
        radius,
    })
}

/// True when detection `d`'s box (a face) is centred within `lm`'s head (see [`face_disc`]).
pub(super) fn detected_face_of(lm: &Landmarks, d: &Detection) -> bool {
    face_disc(lm).is_some_and(|face| face.center.distance(d.center) < face.radius)
}

/// Least radius of a hidden face, in shoulder widths.
const FACE_RADIUS: f32 = 0.5;

/// Landmarks compared to tell one body found twice from two bodies that overlap on screen.
const BODY_POINTS: [usize; 8] = [
    idx::LEFT_SHOULDER,
    idx::RIGHT_SHOULDER,
    idx::LEFT_HIP,
    idx::RIGHT_HIP,
    idx::LEFT_KNEE,
    idx::RIGHT_KNEE,
    idx::LEFT_ANKLE,
    idx::RIGHT_ANKLE,
];

/// True when two landmark sets are the same body: their joints lie on top of each other
/// (mean distance under a tenth of the body's height). People crossing overlap as boxes but
/// not joint by joint. Compared under both labellings: the flip guard may have exchanged one
/// track's left and right (its reference faced the other way), and the same body read with
/// swapped labels is still one body found twice.
pub(super) fn same_body(a: &Landmarks, b: &Landmarks) -> bool {
    body_distance(a, b) < 0.1
}

/// True when two readings put their noses within [`SAME_FACE`] of the wider one's shoulder
/// width: one face, whatever body each reading draws below it (the model reads raised hands in
/// front of a face as a small second body with the same face). Two people's heads overlap in
/// the picture only while one passes behind the other, so this tells a new track from an
/// established one, not two established ones apart (see `PoseTracker::drop_duplicates`).
pub(super) fn same_face(a: &Landmarks, b: &Landmarks) -> bool {
    let point = |lm: &Landmarks, i: usize| Vec2::new(lm.image[i].x, lm.image[i].y);
    let width =
        |lm: &Landmarks| point(lm, idx::LEFT_SHOULDER).distance(point(lm, idx::RIGHT_SHOULDER));
    point(a, idx::NOSE).distance(point(b, idx::NOSE)) < SAME_FACE * width(a).max(width(b))
}

/// See [`same_face`]: a face is about half a shoulder width across.
const SAME_FACE: f32 = 0.25;

/// True when a newly found `found` is `tracked` again: the same body (see [`same_body`]), or
/// the points both see coincide (see [`seen_distance`]; an upper body at a desk read twice,
/// its legs guessed apart). Only for finding people: while two tracked people cross, what
/// both readings see can coincide for a frame or two without their being one. Not the face
/// alone: a person found again behind another has their head beside the other's.
pub(super) fn found_again(tracked: &Landmarks, found: &Landmarks) -> bool {
    same_body(tracked, found) || seen_distance(tracked, found).is_some_and(|d| d < SAME_SEEN)
}

/// Points [`seen_distance`] compares besides [`BODY_POINTS`]: the face and the arms.
const FACE_AND_ARMS: [usize; 9] = [
    idx::NOSE,
    idx::LEFT_EYE,
    idx::RIGHT_EYE,
    idx::LEFT_EAR,
    idx::RIGHT_EAR,
    idx::LEFT_ELBOW,
    idx::RIGHT_ELBOW,
    idx::LEFT_WRIST,
    idx::RIGHT_WRIST,
];

/// Visibility from which a point counts as seen.
const SEEN: f32 = 0.5;

/// Two readings whose seen points lie closer than this (in shoulder widths, see
/// [`seen_distance`]) are one body. On the footage two people came no closer than 0.75 (the
/// pose2sim crossing); one upper body read twice at a desk lay 0.12-0.24 apart.
const SAME_SEEN: f32 = 0.35;

/// The mean distance between the points of [`FACE_AND_ARMS`] and [`BODY_POINTS`] both
/// readings see, under the closer of the two labellings, in the wider of their shoulder
/// widths; None when they share fewer than four. An upper body at a desk has its hips and legs guessed beyond the picture, where
/// two readings of it differ; what both see of it coincides.
fn seen_distance(a: &Landmarks, b: &Landmarks) -> Option<f32> {
    let point = |lm: &Landmarks, i: usize| Vec2::new(lm.image[i].x, lm.image[i].y);
    let width =
        |lm: &Landmarks| point(lm, idx::LEFT_SHOULDER).distance(point(lm, idx::RIGHT_SHOULDER));
    let both = |i: usize, j: usize| a.visibility(i) >= SEEN && b.visibility(j) >= SEEN;
    let mean = |mirrored: bool| {
        let (mut sum, mut n) = (0.0, 0);
        for &i in FACE_AND_ARMS.iter().chain(&BODY_POINTS) {
            let j = if mirrored { mirror_index(i) } else { i };
            if both(i, j) {
                sum += point(a, i).distance(point(b, j));
                n += 1;
            }
        }
        (n >= 4).then(|| sum / n as f32)
    };
    let d = match (mean(false), mean(true)) {
        (Some(x), Some(y)) => x.min(y),
        (x, y) => x.or(y)?,
    };
    Some(d / width(a).max(width(b)).max(1.0))
}

/// How far apart two landmark sets' bodies are: the mean distance of their [`BODY_POINTS`],
/// under the closer of the two labellings, in the taller body's heights.
pub(super) fn body_distance(a: &Landmarks, b: &Landmarks) -> f32 {
    let height = body_box(a).1.y.max(body_box(b).1.y).max(1.0);
    let mean = |mirrored: bool| {
        BODY_POINTS
            .iter()
            .map(|&i| {
                let j = if mirrored { mirror_index(i) } else { i };
                Vec2::new(a.image[i].x - b.image[j].x, a.image[i].y - b.image[j].y).length()
            })
            .sum::<f32>()
            / BODY_POINTS.len() as f32
    };
    mean(false).min(mean(true)) / height
}

/// True when the torso of `next` points more than a quarter turn away from that of `last`
/// (hips to shoulders, in the picture): nobody turns over that fast between two frames (a
/// roll at 30 frames a second turns a tenth of that), but the landmark model does when its
/// crop slides down the legs and it reads the body from the feet up.
pub(super) fn turned_over(last: &Landmarks, next: &Landmarks) -> bool {
    let up = |lm: &Landmarks| {
        let p = |i: usize| Vec2::new(lm.image[i].x, lm.image[i].y);
        p(idx::LEFT_SHOULDER) + p(idx::RIGHT_SHOULDER) - p(idx::LEFT_HIP) - p(idx::RIGHT_HIP)
    };
    up(last).dot(up(next)) < 0.0
}

/// Whether `a` (Some(true)) or `b` (Some(false)) is the upside-down reading of a body the
/// other reads upright: one's body box lies within the other's (at least
/// [`TWIN_CONTAINED`] of the smaller box inside the larger) and only one stands with its
/// shoulders above its hips. The landmark model reads a crop it is not centred on (a detection
/// of the same face, a crop that drifted down the legs) as a body from the feet up; that
/// reading follows itself frame after frame as a second person. Two people whose boxes nest
/// (one behind the other) both stand upright.
pub(super) fn upside_down_twin(a: &Landmarks, b: &Landmarks) -> Option<bool> {
    let upside_down = |lm: &Landmarks| {
        let y = |i: usize| lm.image[i].y;
        y(idx::LEFT_SHOULDER) + y(idx::RIGHT_SHOULDER) > y(idx::LEFT_HIP) + y(idx::RIGHT_HIP)
    };
    let (ua, ub) = (upside_down(a), upside_down(b));
    if ua == ub {
        return None;
    }
    let (ba, bb) = (body_box(a), body_box(b));
    let lo = (ba.0 - ba.1 * 0.5).max(bb.0 - bb.1 * 0.5);
    let hi = (ba.0 + ba.1 * 0.5).min(bb.0 + bb.1 * 0.5);
    let inter = (hi - lo).max(Vec2::ZERO);
    let smaller = (ba.1.x * ba.1.y).min(bb.1.x * bb.1.y).max(1.0);
    (inter.x * inter.y >= TWIN_CONTAINED * smaller).then_some(ua)
}

/// See [`upside_down_twin`].
const TWIN_CONTAINED: f32 = 0.9;

/// True when body box `next` can be the same person as `last` one frame later: about the
/// same height and not far from where they were or from where their last step (`velocity`,
/// the centre's move into `last`) takes them. Two people crossing differ in both (the one
/// behind looks smaller), so a crop that slides from one to the other shows up as a jump;
/// someone running across a small picture moves a third of their height a frame, steadily.
pub(super) fn continues(last: (Vec2, Vec2), velocity: Vec2, next: (Vec2, Vec2)) -> bool {
    let reach = 0.3 * last.1.y.max(1.0);
    similar_height(last, next)
        && (last.0.distance(next.0) < reach || (last.0 + velocity).distance(next.0) < reach)
}

/// True when body box `next` is about as tall as `last` (a quarter shorter to a third taller).
fn similar_height(last: (Vec2, Vec2), next: (Vec2, Vec2)) -> bool {
    similar_length(last.1.y, next.1.y)
}

/// True when length `next` is about `last` (a quarter shorter to a third longer).
pub(super) fn similar_length(last: f32, next: f32) -> bool {
    (0.75..=1.33).contains(&(next.max(1.0) / last.max(1.0)))
}

/// True when `next` shows a body about the size `last` showed (see [`similar_height`]): the
/// whole body's box, or the box of what both see (see [`seen_boxes`]; an upper body's guessed
/// legs change length from one reading to the next).
pub(super) fn same_size(last: &Landmarks, next: &Landmarks) -> bool {
    similar_height(body_box(last), body_box(next))
        || seen_boxes(last, next).is_some_and(|(a, b)| similar_height(a, b))
}

/// The boxes (centre, size; frame pixels) around the landmarks both `last` and `next` see
/// (visibility at least [`SEEN`]), or None when they share fewer than [`MIN_SHARED_SEEN`]: the
/// same person in two frames with what the model guesses beyond the picture left out. An
/// upper body at a desk has legs guessed below the frame whose length changes by a third from
/// one frame to the next, so its whole-body box does not [`continue`](continues) while what is
/// seen of it barely moves.
pub(super) fn seen_boxes(
    last: &Landmarks,
    next: &Landmarks,
) -> Option<((Vec2, Vec2), (Vec2, Vec2))> {
    let mut bounds = [(Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY)); 2];
    let mut shared = 0;
    for i in 0..NUM_LANDMARKS {
        if last.visibility(i) < SEEN || next.visibility(i) < SEEN {
            continue;
        }
        shared += 1;
        for (b, lm) in bounds.iter_mut().zip([last, next]) {
            let p = Vec2::new(lm.image[i].x, lm.image[i].y);
            *b = (b.0.min(p), b.1.max(p));
        }
    }
    let boxed = |(lo, hi): (Vec2, Vec2)| ((lo + hi) * 0.5, hi - lo);
    (shared >= MIN_SHARED_SEEN).then(|| (boxed(bounds[0]), boxed(bounds[1])))
}

/// True when more than half of the points `inner` sees (visibility at least [`SEEN`]) lie
/// within the box around the points `outer` sees (around all of its points when it sees
/// fewer than four).
pub(super) fn mostly_within(inner: &Landmarks, outer: &Landmarks) -> bool {
    fn seen(lm: &Landmarks) -> impl Iterator<Item = usize> + '_ {
        (0..NUM_LANDMARKS).filter(move |&i| lm.visibility(i) >= SEEN)
    }
    let point = |lm: &Landmarks, i: usize| Vec2::new(lm.image[i].x, lm.image[i].y);
    let (mut lo, mut hi) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
    for i in seen(outer) {
        (lo, hi) = (lo.min(point(outer, i)), hi.max(point(outer, i)));
    }
    if seen(outer).count() < 4 {
        let (centre, size) = body_box(outer);
        (lo, hi) = (centre - size * 0.5, centre + size * 0.5);
    }
    let inside = |p: Vec2| p.cmpge(lo).all() && p.cmple(hi).all();
    let within = seen(inner).filter(|&i| inside(point(inner, i))).count();
    2 * within > seen(inner).count()
}

/// True when at least half of the points `lm` sees (visibility at least [`SEEN`]) lie within
/// a `width` × `height` picture: the model also reports points beyond the crop's edge as
/// seen, and a reading that sees mostly beyond the picture's edge (a blurred pan read as a
/// body leaning in from outside) shows nobody in it.
pub(super) fn seen_in_picture(lm: &Landmarks, width: u32, height: u32) -> bool {
    let size = Vec2::new(width as f32, height as f32);
    let (mut seen, mut inside) = (0, 0);
    for p in lm.image[..NUM_LANDMARKS].iter().filter(|p| p.w >= SEEN) {
        seen += 1;
        let p = Vec2::new(p.x, p.y);
        inside += usize::from(p.cmpge(Vec2::ZERO).all() && p.cmplt(size).all());
    }
    seen > 0 && 2 * inside >= seen
}

/// See [`seen_boxes`]: the face alone (11 points) says little about the body's size.
const MIN_SHARED_SEEN: usize = 15;

/// Midpoint of the hips, frame pixels.
pub(super) fn hip_centre(lm: &Landmarks) -> Vec2 {
    let (l, r) = (lm.image[idx::LEFT_HIP], lm.image[idx::RIGHT_HIP]);
    Vec2::new(l.x + r.x, l.y + r.y) * 0.5
}

/// The box around the 33 body landmarks (centre, size), frame pixels.
pub(super) fn body_box(lm: &Landmarks) -> (Vec2, Vec2) {
    let mut lo = Vec2::splat(f32::INFINITY);
    let mut hi = Vec2::splat(f32::NEG_INFINITY);
    for p in &lm.image[..NUM_LANDMARKS] {
        let p = Vec2::new(p.x, p.y);
        if p.is_finite() {
            lo = lo.min(p);
            hi = hi.max(p);
        }
    }
    if lo.x > hi.x {
        return (Vec2::ZERO, Vec2::ZERO);
    }
    ((lo + hi) * 0.5, hi - lo)
}

/// True when the reading `lm` of detection `d`'s crop stands the way the detector saw the
/// person (hips towards head within a quarter turn of the detection's): a reading upside down
/// against its own detection (a crop the model filled with the body's mirror image, the head
/// read at the feet) is nobody the two models agree on.
pub(super) fn upright_as_detected(lm: &Landmarks, d: &Detection) -> bool {
    let point = |i: usize| Vec2::new(lm.image[i].x, lm.image[i].y);
    let read = point(idx::AUX_SCALE) - point(idx::AUX_CENTER);
    read.dot(d.body_scale - d.hip_center) > 0.0
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use crate::vision::sides::{flip_interpretation, LR_PAIRS};
    use glam::{Vec3, Vec4};

    fn person(offset_x: f32) -> Landmarks {
        let mut lm = Landmarks::default();
        for &(l, r) in &LR_PAIRS {
            let y = l as f32 * 10.0;
            lm.image[l] = Vec4::new(offset_x + 50.0, y, 0.0, 1.0);
            lm.image[r] = Vec4::new(offset_x - 50.0, y, 0.0, 1.0);
            lm.world[l] = Vec3::new(0.1 + offset_x * 1e-3, y * 1e-3, 0.0);
            lm.world[r] = Vec3::new(-0.1 + offset_x * 1e-3, y * 1e-3, 0.0);
        }
        lm
    }

    /// The same reading mirrored top to bottom within a 330 px picture.
    fn upside_down(mut lm: Landmarks) -> Landmarks {
        for p in lm.image.iter_mut() {
            p.y = 330.0 - p.y;
        }
        lm
    }

    #[test]
    fn one_body_read_with_swapped_labels_is_still_one_body() {
        let a = person(0.0);
        let mut b = person(4.0);
        flip_interpretation(&mut b);
        assert!(same_body(&a, &b), "a relabelled copy is the same body");
        // Two people side by side (apart by more than their shoulder width) are not.
        assert!(!same_body(&a, &person(300.0)));
        let mut far = person(300.0);
        flip_interpretation(&mut far);
        assert!(!same_body(&a, &far));
    }

    #[test]
    fn one_upper_body_read_twice_is_one_body_whatever_its_guessed_legs() {
        let a = person(0.0);
        let mut b = person(3.0);
        // The legs are beyond the picture: guessed elsewhere, and not seen.
        for i in [
            idx::LEFT_KNEE,
            idx::RIGHT_KNEE,
            idx::LEFT_ANKLE,
            idx::RIGHT_ANKLE,
        ] {
            b.image[i].y += 200.0;
            b.image[i].w = 0.1;
        }
        assert!(!same_body(&a, &b));
        assert!(found_again(&a, &b));
        // Someone beside them, seen as well, is not.
        assert!(!found_again(&a, &person(120.0)));
    }

    #[test]
    fn an_upper_body_whose_guessed_legs_shrink_continues_by_what_is_seen() {
        let last = person(0.0);
        let mut next = person(2.0);
        // The legs (beyond the picture, not seen) guessed half as long as a frame before.
        for p in next.image[idx::LEFT_HIP..NUM_LANDMARKS].iter_mut() {
            p.y = 230.0;
            p.w = 0.1;
        }
        assert!(!continues(body_box(&last), Vec2::ZERO, body_box(&next)));
        let (a, b) = seen_boxes(&last, &next).unwrap();
        assert!(continues(a, Vec2::ZERO, b));
        // Someone else seen where the person was is not them.
        let (a, b) = seen_boxes(&last, &person(150.0)).unwrap();
        assert!(!continues(a, Vec2::ZERO, b));
        // Too little seen in both says nothing.
        let mut faint = person(0.0);
        for p in faint.image.iter_mut().skip(11) {
            p.w = 0.1;
        }
        assert!(seen_boxes(&last, &faint).is_none());
    }

    #[test]
    fn a_steady_runner_continues_where_their_step_takes_them() {
        let last = (Vec2::new(100.0, 100.0), Vec2::new(40.0, 50.0));
        // A third of their height a frame to the left, as in the frame before.
        let next = (Vec2::new(80.0, 100.0), Vec2::new(40.0, 52.0));
        assert!(!continues(last, Vec2::ZERO, next));
        assert!(continues(last, Vec2::new(-20.0, 0.0), next));
        // Stopping dead still continues; a step the other way does not.
        assert!(continues(last, Vec2::new(-20.0, 0.0), last));
        assert!(!continues(last, Vec2::new(20.0, 0.0), next));
        // Half the height is another body, wherever it is.
        let small = (Vec2::new(80.0, 100.0), Vec2::new(20.0, 25.0));
        assert!(!continues(last, Vec2::new(-20.0, 0.0), small));
    }

    #[test]
    fn a_body_of_another_size_is_not_the_person_taken_back() {
        let last = person(0.0);
        assert!(same_size(&last, &person(20.0)));
        let mut small = person(0.0);
        for p in small.image.iter_mut() {
            p.y *= 0.4;
        }
        assert!(!same_size(&last, &small));
        // An upper body whose guessed legs shrink is still its size by what is seen.
        let mut legs = person(2.0);
        for p in legs.image[idx::LEFT_HIP..NUM_LANDMARKS].iter_mut() {
            p.y = 230.0;
            p.w = 0.1;
        }
        assert!(same_size(&last, &legs));
    }

    #[test]
    fn a_reading_that_sees_mostly_within_a_tracked_body_is_not_someone_new() {
        let tracked = person(0.0);
        // Arms and what they hold, read as a small body on the tracked one's chest.
        let mut arms = person(0.0);
        for p in arms.image.iter_mut() {
            p.x *= 0.5;
            p.y = 100.0 + 0.3 * p.y;
        }
        assert!(mostly_within(&arms, &tracked));
        // Someone beside them, overlapping by an arm, is someone.
        assert!(!mostly_within(&person(90.0), &tracked));
        // What is not seen does not count: a body whose seen points lie beside.
        let mut beside = person(200.0);
        for i in [idx::LEFT_WRIST, idx::LEFT_ELBOW] {
            beside.image[i].x = 10.0;
        }
        assert!(!mostly_within(&beside, &tracked));
    }

    #[test]
    fn a_reading_that_sees_mostly_beyond_the_picture_shows_nobody_in_it() {
        // Left points at x 250, right at 150, all seen, y up to 310.
        let lm = person(200.0);
        assert!(seen_in_picture(&lm, 400, 400));
        assert!(!seen_in_picture(&lm, 100, 400));
        // Half of it in the picture: someone at its edge.
        assert!(seen_in_picture(&lm, 200, 400));
        // What is not seen does not count.
        let mut faint = lm;
        for &(l, _) in &LR_PAIRS {
            faint.image[l].w = 0.1;
        }
        assert!(seen_in_picture(&faint, 200, 400));
        assert!(!seen_in_picture(&Landmarks::default(), 400, 400));
    }

    #[test]
    fn two_readings_with_one_nose_share_a_face() {
        let with_nose = |offset_x: f32| {
            let mut lm = person(offset_x);
            lm.image[idx::NOSE] = Vec4::new(offset_x, 5.0, 0.0, 1.0);
            lm
        };
        let a = with_nose(0.0);
        // Another body drawn below the same face (shoulders 100 px wide).
        let mut b = with_nose(300.0);
        b.image[idx::NOSE] = a.image[idx::NOSE] + Vec4::new(5.0, 5.0, 0.0, 0.0);
        assert!(same_face(&a, &b));
        // Two heads side by side, closer than their shoulders are wide, are two faces.
        assert!(!same_face(&a, &with_nose(60.0)));
    }

    #[test]
    fn a_torso_turned_over_within_a_frame_is_a_misreading() {
        let upright = person(0.0);
        let over = upside_down(upright);
        assert!(turned_over(&upright, &over));
        assert!(!turned_over(&upright, &person(30.0)));
        // A sixth of a turn in one frame is a fast roll, not a misreading.
        let mut rolled = upright;
        for p in rolled.image.iter_mut() {
            let (x, y) = (p.x, p.y);
            p.x = 0.5 * x - 0.866 * y;
            p.y = 0.866 * x + 0.5 * y;
        }
        assert!(!turned_over(&upright, &rolled));
    }

    #[test]
    fn an_upside_down_reading_inside_an_upright_body_is_its_twin() {
        let upright = person(0.0);
        let misread = upside_down(upright);
        assert_eq!(upside_down_twin(&upright, &misread), Some(false));
        assert_eq!(upside_down_twin(&misread, &upright), Some(true));
        // Two upright people whose boxes nest are two people; so is someone upside down
        // beside an upright person.
        let mut behind = person(20.0);
        for p in behind.image.iter_mut() {
            p.y = 100.0 + 0.5 * p.y;
        }
        assert_eq!(upside_down_twin(&upright, &behind), None);
        let beside = upside_down(person(150.0));
        assert_eq!(upside_down_twin(&upright, &beside), None);
    }

    #[test]
    fn a_detection_of_a_tracked_face_is_that_person_whatever_hips_it_guesses() {
        let mut lm = person(0.0);
        lm.image[idx::NOSE] = Vec4::new(0.0, 5.0, 0.0, 1.0);
        let d = |x: f32| Detection {
            score: 0.9,
            center: Vec2::new(x, 8.0),
            size: Vec2::splat(40.0),
            hip_center: Vec2::new(x + 200.0, 400.0),
            body_scale: Vec2::new(x, 0.0),
        };
        // Shoulders 100 px apart: a head half that across.
        assert!(detected_face_of(&lm, &d(20.0)));
        assert!(!detected_face_of(&lm, &d(120.0)));
    }

    #[test]
    fn a_reading_upside_down_against_its_detection_is_refused() {
        let mut lm = person(0.0);
        lm.image[idx::AUX_CENTER] = Vec4::new(0.0, 200.0, 0.0, 1.0);
        lm.image[idx::AUX_SCALE] = Vec4::new(0.0, 50.0, 0.0, 1.0);
        let mut d = Detection {
            score: 0.9,
            center: Vec2::new(0.0, 40.0),
            size: Vec2::splat(40.0),
            hip_center: Vec2::new(10.0, 190.0),
            body_scale: Vec2::new(30.0, 60.0),
        };
        assert!(upright_as_detected(&lm, &d));
        d.body_scale = Vec2::new(0.0, 330.0);
        assert!(!upright_as_detected(&lm, &d));
    }
}
