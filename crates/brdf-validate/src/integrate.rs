//! The independent integrator behind every expected cell mass: Gauss–Kronrod 7–15 with
//! QUADPACK's globally adaptive strategy (QAG), first cut at break points (QAGP). It never
//! looks at a sampler's tree, so a wrong leaf integral or bound cannot hide in it.

/// The error estimate, relative to ∫|f| over a piece, below which [`adaptive`] does not halve
/// the piece: 4·2⁻²⁴, four times the rounding of an f32 value. The integrands are models' f32
/// values (and f32 pdfs), so a piece's Gauss–Kronrod difference cannot fall much below this
/// however far it is halved (pure rounding gives at most an eighth of it: over 50 000 pieces
/// of a smooth f rounded to f32, widths 10⁻⁷ to 10⁻², at most 0.50·2⁻²⁴ of ∫|f|, median
/// 0.08·2⁻²⁴); a tolerance under it only spent evaluations chasing rounding: every piece of
/// every cell refined to the limit, nested (`brdf test --tol 1e-10` on htsg had not
/// finished after 600 s; `--tol 1e-9` with `--cells 2`, 144 s, against 1.6 s at the
/// default 10⁻⁷).
pub(crate) const NOISE: f64 = 4.0 / 16_777_216.0;

/// Most intervals one adaptive integration may split its range into.
pub(crate) const MAX_PIECES: usize = 200;
/// Most break points one adaptive integration starts from: a polar cell's range in φ is cut
/// at each of up to 12 peaks and at two points for each of up to 24 ridge planes (see
/// `CellGrid::integrate`).
pub(crate) const MAX_BREAKS: usize = 64;
/// Most equal pieces [`adaptive`] cuts one first piece into for a staircase's steps.
pub(crate) const STEP_PIECES: usize = 64;
/// Most levels of pieces halving toward a break where f spikes (see [`adaptive`]).
const GRADING: usize = 40;

/// Gauss–Kronrod 7–15 nodes on [0, 1] (QUADPACK's qk15), largest first; the last is 0.
const XGK: [f64; 8] = [
    0.991_455_371_120_812_6,
    0.949_107_912_342_758_5,
    0.864_864_423_359_769_1,
    0.741_531_185_599_394_4,
    0.586_087_235_467_691_1,
    0.405_845_151_377_397_2,
    0.207_784_955_007_898_5,
    0.0,
];
/// Kronrod weights for [`XGK`].
const WGK: [f64; 8] = [
    0.022_935_322_010_529_22,
    0.063_092_092_629_978_55,
    0.104_790_010_322_250_2,
    0.140_653_259_715_525_9,
    0.169_004_726_639_267_9,
    0.190_350_578_064_785_4,
    0.204_432_940_075_298_9,
    0.209_482_141_084_727_8,
];
/// Gauss weights for the odd-indexed nodes XGK[1], XGK[3], XGK[5] and XGK[7].
const WG: [f64; 4] = [
    0.129_484_966_168_869_7,
    0.279_705_391_489_276_7,
    0.381_830_050_505_118_9,
    0.417_959_183_673_469_4,
];

/// What [`gk15`] finds on one interval: the Kronrod estimate of ∫_a^b f and |Kronrod −
/// Gauss|, with f at its midpoint and at its two outermost nodes (0.43 % of the interval
/// from each end).
struct Rule {
    value: f64,
    err: f64,
    /// The Kronrod rule applied to |f|: the scale of the rounding in f's values.
    abs: f64,
    mid: f64,
    ends: (f64, f64),
}

/// Gauss–Kronrod 7–15 on [a, b].
fn gk15(f: &(impl Fn(f64) -> f64 + ?Sized), a: f64, b: f64) -> Rule {
    let (c, h) = (0.5 * (a + b), 0.5 * (b - a));
    let fc = f(c);
    let (mut k, mut g) = (WGK[7] * fc, WG[3] * fc);
    let mut abs = WGK[7] * fc.abs();
    let mut ends = (0.0, 0.0);
    for j in 0..7 {
        let (x, w) = (XGK[j] * h, WGK[j]);
        let (lo, hi) = (f(c - x), f(c + x));
        if j == 0 {
            ends = (lo, hi);
        }
        let s = lo + hi;
        k += w * s;
        abs += w * (lo.abs() + hi.abs());
        if j % 2 == 1 {
            g += WG[j / 2] * s;
        }
    }
    Rule {
        value: k * h,
        err: (k - g).abs() * h,
        abs: abs * h,
        mid: fc,
        ends,
    }
}

/// The error a jump of f may hide between a piece's outermost node (f there: `node`) and
/// its end, where f is known (`end`; NaN where it is not): none unless f differs there by
/// over a tenth of the larger of the two (a smooth f, resolved, differs by its slope times
/// 0.43 % of the piece), else that difference over the 0.43 % of `width` the rule does
/// not see.
fn hidden_jump(end: f64, node: f64, width: f64) -> f64 {
    let d = (end - node).abs();
    if d > 0.1 * end.abs().max(node.abs()) {
        d * 0.5 * (1.0 - XGK[0]) * width
    } else {
        0.0
    }
}

/// Globally adaptive [`gk15`] (QUADPACK's QAG strategy): keep bisecting the interval with the
/// largest error estimate until the estimates sum to at most `tol`, or `limit` intervals
/// exist; an interval whose estimate is within the rounding of f's values ([`NOISE`]) is
/// set aside instead (still counted and summed), and the loop also ends when none but
/// those is left. Unlike halving the tolerance per level, this spends evaluations only where the
/// error is: a kink or a jump costs one chain of bisections, not a full-depth tree, and the
/// limit bounds the work on integrands that never meet the tolerance. A half's estimate
/// also counts a jump of f between its outermost node and an end where a bisection has
/// evaluated f (see [`hidden_jump`]), which the rule alone cannot see; a smooth f never
/// trips it, and is integrated bit for bit as by plain QAG.
///
/// `breaks` (at most [`MAX_BREAKS`] are used): points where f may peak (a model's peak
/// hints). The range is first cut at those inside it, QUADPACK's QAGP: a lobe narrower than
/// the spacing of the 15 nodes then sits at the end of a piece, beside its outermost node,
/// instead of between two nodes, where every node sees 0, the error estimate is 0 and the
/// lobe is lost. A lobe narrower still, within 0.4 % of a piece of its break, is missed by
/// the outermost node too: where f at a break spikes over f at the nearest node beside it,
/// that side's piece is first graded toward the break (see the body). Without a break
/// inside (a, b) this is plain QAG, bit for bit.
///
/// `max_piece`: for a staircase integrand (a table read by nearest bin,
/// [`brdf_core::Brdf::step_width`]), the width of its steps in the variable of integration;
/// ∞ otherwise. Each first piece wider than it is cut into equal pieces no wider (at most
/// [`STEP_PIECES`] of them) before the bisection starts: over a piece that holds many steps,
/// the Gauss and Kronrod sums of a staircase can agree by chance while both are off, and the
/// loop would stop there. (A baked sampler's pdf on a MERL table, summed over 25 × 25
/// cells, came out 6·10⁻⁴ above what it draws, and 3·10⁻⁴ on the polar grid; cut to 1°
/// pieces, within 2·10⁻⁵ on both, and no slower.)
#[allow(clippy::too_many_arguments)]
pub(crate) fn adaptive(
    f: &(impl Fn(f64) -> f64 + ?Sized),
    a: f64,
    b: f64,
    breaks: &[f64],
    max_piece: f64,
    tol: f64,
    limit: usize,
) -> f64 {
    /// An interval with its estimate and error, ordered by error (ties by position, so the
    /// order of bisection is fully determined by the integrand).
    struct Piece {
        a: f64,
        b: f64,
        value: f64,
        err: f64,
        /// ∫|f| by the Kronrod rule (see [`NOISE`]).
        abs: f64,
        /// f at the midpoint.
        mid: f64,
        /// f at the two ends, where a bisection found it (a parent's midpoint), else NaN.
        ends: (f64, f64),
    }
    impl PartialEq for Piece {
        fn eq(&self, other: &Self) -> bool {
            self.cmp(other) == core::cmp::Ordering::Equal
        }
    }
    impl Eq for Piece {}
    impl PartialOrd for Piece {
        fn partial_cmp(&self, other: &Self) -> Option<core::cmp::Ordering> {
            Some(self.cmp(other))
        }
    }
    impl Ord for Piece {
        fn cmp(&self, other: &Self) -> core::cmp::Ordering {
            self.err
                .total_cmp(&other.err)
                .then(other.a.total_cmp(&self.a))
        }
    }
    // The ends of the first pieces: a, the breaks inside (a, b) in order, b.
    let mut ends = [a; MAX_BREAKS + 2];
    let mut n = 1;
    for &x in breaks.iter().take(MAX_BREAKS) {
        if x > a && x < b {
            ends[n] = x;
            n += 1;
        }
    }
    ends[1..n].sort_unstable_by(f64::total_cmp);
    ends[n] = b;
    n += 1;
    // A lobe centred on a break and narrower than the distance from a piece's end to its
    // outermost node (0.4 % of the piece) is missed by the pieces beside it. Where f at the
    // break is over twice f at that distance on both sides of it (a peak, not a jump: by a
    // jump one side stays high), the piece is graded toward the break: ends at a half, a
    // quarter... of it from the break, until the nearest node of the last sees at least half
    // of f at the break (or GRADING levels), so that the adaptive loop below sees the lobe.
    // A smooth f costs at most five evaluations a break and grades nothing.
    let near = 0.5 * (1.0 - XGK[0]);
    // toward[i]: whether the piece before end i, and the one after it, are graded.
    let mut toward = [(false, false); MAX_BREAKS + 2];
    let mut peak = [0.0; MAX_BREAKS + 2];
    for i in 1..n - 1 {
        let (l, x, r) = (ends[i - 1], ends[i], ends[i + 1]);
        peak[i] = f(x).abs();
        let peaks_within =
            |d: f64| d > 0.0 && peak[i] > 2.0 * f(x - d).abs() && peak[i] > 2.0 * f(x + d).abs();
        toward[i] = (peaks_within(near * (x - l)), peaks_within(near * (r - x)));
    }
    let mut cuts = Vec::with_capacity(2 * n + 2);
    // Ends graded from `x` toward `x + d` (d of either sign).
    let grade = |cuts: &mut Vec<f64>, x: f64, d: f64, fx: f64| {
        let mut step = d;
        for _ in 0..GRADING {
            step *= 0.5;
            let y = x + step;
            if y == x {
                break;
            }
            cuts.push(y);
            if f(x + near * step).abs() >= 0.5 * fx {
                break;
            }
        }
    };
    for i in 0..n - 1 {
        let (l, r) = (ends[i], ends[i + 1]);
        cuts.push(l);
        let (from_l, from_r) = (toward[i].1, toward[i + 1].0);
        let d = if from_l && from_r {
            0.5 * (r - l)
        } else {
            r - l
        };
        if from_l {
            grade(&mut cuts, l, d, peak[i]);
        }
        if from_r {
            grade(&mut cuts, r, -d, peak[i + 1]);
        }
    }
    cuts.push(b);
    cuts.sort_unstable_by(f64::total_cmp);
    if max_piece < b - a {
        let mut within = Vec::new();
        for w in cuts.windows(2) {
            let k = ((w[1] - w[0]) / max_piece).ceil().min(STEP_PIECES as f64) as usize;
            within.extend((1..k).map(|j| w[0] + (w[1] - w[0]) * (j as f64 / k as f64)));
        }
        cuts.extend(within);
        cuts.sort_unstable_by(f64::total_cmp);
    }
    let mut heap = std::collections::BinaryHeap::with_capacity(limit.min(1024));
    let (mut total_err, mut finite) = (0.0, true);
    for w in cuts.windows(2) {
        if w[1] > w[0] {
            let r = gk15(f, w[0], w[1]);
            finite &= r.err.is_finite();
            total_err += r.err;
            heap.push(Piece {
                a: w[0],
                b: w[1],
                value: r.value,
                err: r.err,
                abs: r.abs,
                mid: r.mid,
                ends: (f64::NAN, f64::NAN),
            });
        }
    }
    // Pieces whose error estimate is within the rounding of f's own values: never halved.
    let mut settled = Vec::new();
    while finite && total_err > tol && heap.len() + settled.len() < limit {
        let Some(p) = heap.pop() else { break };
        if p.err <= NOISE * p.abs {
            settled.push(p);
            continue;
        }
        let c = 0.5 * (p.a + p.b);
        if !(c > p.a && c < p.b) {
            // The interval cannot be split in f64: keep it as it is and stop.
            heap.push(p);
            break;
        }
        let (r0, r1) = (gk15(f, p.a, c), gk15(f, c, p.b));
        if !(r0.err.is_finite() && r1.err.is_finite()) {
            heap.push(p);
            break;
        }
        // A jump just short of an end, past a half's outermost node, is invisible to that
        // half's estimate: halving a piece over a cap's edge so made its error vanish (a
        // polar cell's mass came out 0.8 % high at tolerance 10⁻⁷). f is known at the
        // midpoint the halves share (the parent's) and at whichever of the parent's ends an
        // earlier halving made, and shows it; each later halving keeps the end in view.
        let (l, r) = ((p.ends.0, p.mid), (p.mid, p.ends.1));
        let e0 = r0
            .err
            .max(hidden_jump(l.0, r0.ends.0, c - p.a))
            .max(hidden_jump(l.1, r0.ends.1, c - p.a));
        let e1 = r1
            .err
            .max(hidden_jump(r.0, r1.ends.0, p.b - c))
            .max(hidden_jump(r.1, r1.ends.1, p.b - c));
        total_err += e0 + e1 - p.err;
        heap.push(Piece {
            a: p.a,
            b: c,
            value: r0.value,
            err: e0,
            abs: r0.abs,
            mid: r0.mid,
            ends: l,
        });
        heap.push(Piece {
            a: c,
            b: p.b,
            value: r1.value,
            err: e1,
            abs: r1.abs,
            mid: r1.mid,
            ends: r,
        });
    }
    // Sum in order of position, so the result does not depend on the heap's layout.
    let mut pieces = heap.into_vec();
    pieces.append(&mut settled);
    pieces.sort_unstable_by(|x, y| x.a.total_cmp(&y.a));
    pieces.iter().map(|p| p.value).sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use brdf_core::math as m;
    use std::f64::consts::PI;

    #[test]
    fn gauss_kronrod_rules_are_exact_to_their_degree() {
        for k in 0..=22 {
            let kr = gk15(&|x: f64| m::pow(x, f64::from(k)), 0.0, 1.0).value;
            assert!((kr - 1.0 / f64::from(k + 1)).abs() < 1e-15, "K15 x^{k}");
        }
        // The embedded Gauss rule is exact to degree 13, so the error estimate vanishes there.
        for k in 0..=13 {
            let err = gk15(&|x: f64| m::pow(x, f64::from(k)), 0.0, 1.0).err;
            assert!(err < 1e-15, "G7 x^{k}: {err}");
        }
        let s = adaptive(
            &|x: f64| m::sqrt(x),
            0.0,
            1.0,
            &[],
            f64::INFINITY,
            1e-12,
            200,
        );
        assert!((s - 2.0 / 3.0).abs() < 1e-11);
    }

    /// A jump just short of a bisection's midpoint, between a half's outermost node and
    /// the end it shares with its sibling, is invisible to that half's Gauss–Kronrod
    /// estimate; the parent's f at the midpoint shows it, and the integral meets its
    /// tolerance (it stopped 10⁻⁴ off at a tolerance of 10⁻¹⁰, its error estimate 0). The
    /// mirrored step, and a step too small to count as a jump (5 %), are integrated too.
    #[test]
    fn a_jump_hidden_beside_a_midpoint_is_found() {
        for (edge, low, high, mirrored) in [
            (0.4999, 0.0, 1.0, false),
            (0.5001, 0.0, 1.0, true),
            (0.4999, 0.95, 1.0, false),
        ] {
            let step = |x: f64| {
                let left = if mirrored { x > edge } else { x < edge };
                if left { high } else { low }
            };
            let exact = if mirrored {
                high * (1.0 - edge) + low * edge
            } else {
                high * edge + low * (1.0 - edge)
            };
            let s = adaptive(&step, 0.0, 1.0, &[], f64::INFINITY, 1e-10, MAX_PIECES);
            let tol = if low == 0.0 { 1e-9 } else { 1e-5 };
            assert!(
                (s - exact).abs() < tol,
                "edge {edge} low {low}: {s} vs {exact}"
            );
        }
    }

    #[test]
    fn adaptive_resolves_kinks_and_jumps_with_few_evaluations() {
        let count = core::cell::Cell::new(0u32);
        let c = 1.0 / PI;
        let kink = |x: f64| {
            count.set(count.get() + 1);
            (x - c).abs()
        };
        let exact = 0.5 * (c * c + (1.0 - c) * (1.0 - c));
        let s = adaptive(&kink, 0.0, 1.0, &[], f64::INFINITY, 1e-12, MAX_PIECES);
        assert!((s - exact).abs() < 1e-12, "{s} vs {exact}");
        // One chain of bisections toward the kink, not a full-depth tree.
        assert!(count.get() < 1500, "{} evaluations", count.get());
        count.set(0);
        let jump = |x: f64| {
            count.set(count.get() + 1);
            if x < c { 1.0 } else { 3.0 }
        };
        let s = adaptive(&jump, 0.0, 1.0, &[], f64::INFINITY, 1e-9, MAX_PIECES);
        assert!((s - (c + 3.0 * (1.0 - c))).abs() < 1e-9, "{s}");
        assert!(count.get() < 2000, "{} evaluations", count.get());
        // The limit bounds the work when the tolerance cannot be met.
        count.set(0);
        let _ = adaptive(&jump, 0.0, 1.0, &[], f64::INFINITY, 0.0, 50);
        assert!(count.get() <= 15 * (2 * 50), "{} evaluations", count.get());
    }

    /// A lobe centred on a break, far narrower than the nodes' distance from the piece's
    /// end, is found by grading toward the break; a smooth f with the same break costs five
    /// evaluations more than the plain cut, and a jump at the break grades nothing.
    #[test]
    fn a_needle_on_a_break_is_found_and_a_smooth_peak_costs_nothing() {
        let c = 1.0 / PI;
        for width in [1e-4, 1e-6] {
            let needle = |x: f64| m::exp(-((x - c) / width).powi(2));
            let exact = width * PI.sqrt();
            let s = adaptive(&needle, 0.0, 1.0, &[c], f64::INFINITY, 1e-12, MAX_PIECES);
            assert!(
                (s - exact).abs() < 1e-6 * exact,
                "width {width}: {s} vs {exact}"
            );
        }
        // (Without the grading the 10⁻⁶ needle integrates to 8·10⁻¹⁸.)
        let count = core::cell::Cell::new(0u32);
        let smooth = |x: f64| {
            count.set(count.get() + 1);
            m::exp(-((x - c) / 0.3).powi(2))
        };
        let _ = adaptive(&smooth, 0.0, 1.0, &[c], f64::INFINITY, 1e-3, MAX_PIECES);
        assert!(count.get() <= 2 * 15 + 5, "{} evaluations", count.get());
        count.set(0);
        let jump = |x: f64| {
            count.set(count.get() + 1);
            if x < c { 0.0 } else { 1.0 }
        };
        let s = adaptive(&jump, 0.0, 1.0, &[c], f64::INFINITY, 1e-3, MAX_PIECES);
        // Constant on both pieces: exact, with no grading and no bisection.
        assert_eq!(s, 1.0 - c);
        assert!(count.get() <= 2 * 15 + 5, "{} evaluations", count.get());
    }
}
