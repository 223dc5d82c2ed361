//! The foot lock's one-dimensional searches (the body's height, a foot's lift and its move
//! over the ground): each minimises a smooth cost of one length.

/// Where in `[lo, hi]` `cost` is least: first `scan` evenly spaced samples, as the cost need
/// not have one minimum over the whole range (with fewer than 2, the whole range is taken to
/// have one), then `steps` golden-section steps between the best sample's neighbours (the
/// bracket shrinks 0.618 a step).
pub(crate) fn least_between(
    cost: impl Fn(f32) -> f32,
    lo: f32,
    hi: f32,
    scan: usize,
    steps: usize,
) -> f32 {
    let (mut a, mut b) = if scan >= 2 {
        let at = sample_at(lo, hi, scan);
        let best = best_sample(&cost, at, scan).0;
        (at(best.saturating_sub(1)), at((best + 1).min(scan - 1)))
    } else {
        (lo, hi)
    };
    let k = 0.5 * (5f32.sqrt() - 1.0);
    let (mut c, mut d) = (b - k * (b - a), a + k * (b - a));
    let (mut fc, mut fd) = (cost(c), cost(d));
    for _ in 0..steps {
        if fc < fd {
            (b, d, fd) = (d, c, fc);
            c = b - k * (b - a);
            fc = cost(c);
        } else {
            (a, c, fc) = (c, d, fd);
            d = a + k * (b - a);
            fd = cost(d);
        }
    }
    0.5 * (a + b)
}

/// The `k`-th of `scan` (at least 2) evenly spaced samples over `[lo, hi]`.
fn sample_at(lo: f32, hi: f32, scan: usize) -> impl Fn(usize) -> f32 + Copy {
    let step = (hi - lo) / (scan - 1) as f32;
    move |k| lo + step * k as f32
}

/// The sample of least cost and its cost: each sample's cost once (a comparison sort would
/// ask for most of them twice), the first of equal least costs, as `min_by` gives.
fn best_sample(cost: &impl Fn(f32) -> f32, at: impl Fn(usize) -> f32, scan: usize) -> (usize, f32) {
    let mut best = (0, f32::NAN);
    for k in 0..scan {
        let c = cost(at(k));
        if k == 0 || c.total_cmp(&best.1).is_lt() {
            best = (k, c);
        }
    }
    best
}

/// Where in `[lo, hi]` `cost` is least, to within `tol` (in `cost`'s argument): first `scan`
/// evenly spaced samples (at least 2), as the cost need not have one minimum over the whole
/// range, then Brent's steps between the best sample's neighbours: a parabola through the
/// three best points so far where it falls well inside the bracket, a golden-section step
/// where it does not, stopping once the bracket is within `tol` of the best point either way
/// (or after `max_steps`). On a smooth minimum the parabola converges in a few steps where a
/// golden section shrinks the bracket 0.618 a step whatever the cost's shape; at a kink (a
/// leg at full stretch) the golden steps keep the section's worst case. The best point
/// evaluated is returned, so its cost is never above the best sample's.
pub(crate) fn least_within(
    cost: impl Fn(f32) -> f32,
    (lo, hi): (f32, f32),
    scan: usize,
    tol: f32,
    max_steps: usize,
) -> f32 {
    let scan = scan.max(2);
    let at = sample_at(lo, hi, scan);
    let (k, fx) = best_sample(&cost, at, scan);
    let bracket = (at(k.saturating_sub(1)), at((k + 1).min(scan - 1)));
    brent(cost, bracket, (at(k), fx), tol.max(0.0), max_steps)
}

/// Brent's minimisation over `(a, b)` from `x` inside it (its cost `fx`), to within `tol`.
fn brent(
    cost: impl Fn(f32) -> f32,
    (mut a, mut b): (f32, f32),
    (mut x, mut fx): (f32, f32),
    tol: f32,
    max_steps: usize,
) -> f32 {
    // The golden section's smaller share.
    let golden = 0.5 * (3.0 - 5f32.sqrt());
    let (mut w, mut fw, mut v, mut fv) = (x, fx, x, fx);
    // The last two steps' lengths: a parabola is trusted only while steps keep shrinking.
    let (mut d, mut e) = (0.0f32, 0.0f32);
    for _ in 0..max_steps {
        let m = 0.5 * (a + b);
        if (x - m).abs() <= 2.0 * tol - 0.5 * (b - a) {
            break;
        }
        let mut parabolic = false;
        if e.abs() > tol {
            let r = (x - w) * (fx - fv);
            let q = (x - v) * (fx - fw);
            let p = (x - v) * q - (x - w) * r;
            let q = 2.0 * (q - r);
            let (p, q) = if q > 0.0 { (-p, q) } else { (p, -q) };
            // Inside the bracket, and less than half the step before last.
            if p.abs() < (0.5 * q * e).abs() && p > q * (a - x) && p < q * (b - x) {
                e = d;
                d = p / q;
                let u = x + d;
                if u - a < 2.0 * tol || b - u < 2.0 * tol {
                    d = tol.copysign(m - x);
                }
                parabolic = true;
            }
        }
        if !parabolic {
            e = if x >= m { a - x } else { b - x };
            d = golden * e;
        }
        // Never a step shorter than the tolerance: the cost cannot tell nearer points apart.
        let u = if d.abs() >= tol {
            x + d
        } else {
            x + tol.copysign(d)
        };
        let fu = cost(u);
        if fu <= fx {
            if u >= x {
                a = x;
            } else {
                b = x;
            }
            (v, fv, w, fw, x, fx) = (w, fw, x, fx, u, fu);
        } else {
            if u < x {
                a = u;
            } else {
                b = u;
            }
            if fu <= fw || w == x {
                (v, fv, w, fw) = (w, fw, u, fu);
            } else if fu <= fv || v == x || v == w {
                (v, fv) = (u, fu);
            }
        }
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_the_least_of_a_parabola_and_the_lower_of_two_valleys() {
        let x = least_between(|x| (x - 0.3) * (x - 0.3), -1.0, 1.0, 0, 40);
        assert!((x - 0.3).abs() < 1e-4, "{x}");
        // Two valleys, the deeper at 0.7: golden steps alone over the range may end in
        // either; the scan picks the deeper.
        let two = |x: f32| ((x + 0.6) * (x + 0.6)).min((x - 0.7) * (x - 0.7) - 0.1);
        let x = least_between(two, -1.0, 1.0, 9, 40);
        assert!((x - 0.7).abs() < 1e-3, "{x}");
    }

    #[test]
    fn brent_finds_a_smooth_minimum_in_few_steps_and_a_kink_to_the_tolerance() {
        use std::cell::Cell;
        let calls = Cell::new(0);
        let counted = |f: &dyn Fn(f32) -> f32, x: f32| {
            calls.set(calls.get() + 1);
            f(x)
        };
        let tol = 1e-5;
        // A smooth valley off the scan's samples: the parabola lands on it in a few steps
        // (a golden section would take ~16 from the scan's quarter of the range).
        let smooth = |x: f32| (x - 0.0371) * (x - 0.0371) + 0.3 * (x - 0.0371).powi(4);
        let x = least_within(|x| counted(&smooth, x), (-0.1, 0.1), 9, tol, 40);
        assert!((x - 0.0371).abs() <= tol, "{x}");
        assert!(calls.get() <= 9 + 8, "{} evaluations", calls.get());
        // A kink (a V: no parabola fits it): still within the tolerance.
        calls.set(0);
        let kink = |x: f32| (x + 0.0123).abs();
        let x = least_within(|x| counted(&kink, x), (-0.1, 0.1), 9, tol, 40);
        assert!((x + 0.0123).abs() <= 2.0 * tol, "{x}");
        assert!(calls.get() <= 9 + 40, "{} evaluations", calls.get());
        // At an end of the range.
        let x = least_within(|x| x, (-0.1, 0.1), 9, tol, 40);
        assert!((x + 0.1).abs() <= 2.0 * tol, "{x}");
        // Two valleys, the deeper at 0.7: the scan picks it.
        let two = |x: f32| ((x + 0.6) * (x + 0.6)).min((x - 0.7) * (x - 0.7) - 0.1);
        let x = least_within(two, (-1.0, 1.0), 9, tol, 40);
        assert!((x - 0.7).abs() < 1e-3, "{x}");
    }
}
