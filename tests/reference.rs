//! An independent f64 evaluation of MODELS.md's twelve formulas, written from the document and
//! sharing no code with the library: the oracle `brdf eval` is checked against.
//!
//! Where the library is clever the reference is plain: HTSG sums its series term by term from
//! m = 1 with ln m! accumulated, its own erf/erfc and a bisection for Lambert W; Poulin-Fournier
//! finds what is lit and seen by casting 2D rays against the neighbouring circles on a fine
//! grid of surface points, refines each visibility change by bisection and integrates the
//! pieces with adaptive Simpson.

use std::f64::consts::PI;

pub type V = [f64; 3];

fn dot(a: V, b: V) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn normalize(a: V) -> V {
    let l = dot(a, a).sqrt();
    [a[0] / l, a[1] / l, a[2] / l]
}

fn half(wi: V, wo: V) -> V {
    normalize([wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]])
}

fn cos_alpha(wi: V, wo: V) -> f64 {
    dot([-wi[0], -wi[1], wi[2]], wo).max(0.0)
}

fn cos_dphi(wi: V, wo: V) -> f64 {
    let (li, lo) = (wi[0].hypot(wi[1]), wo[0].hypot(wo[1]));
    if li == 0.0 || lo == 0.0 {
        0.0
    } else {
        (wi[0] * wo[0] + wi[1] * wo[1]) / (li * lo)
    }
}

/// pow with pow(0, 0) = 1.
fn pw(x: f64, n: f64) -> f64 {
    if n == 0.0 { 1.0 } else { x.powf(n) }
}

/// f_r per channel for model `name` with named scalar parameters (one channel at a time),
/// at unit directions; 0 below the horizon.
pub fn eval(name: &str, p: &dyn Fn(&str) -> f64, wi: V, wo: V) -> f64 {
    if wi[2] <= 0.0 || wo[2] <= 0.0 {
        return 0.0;
    }
    let (ci, co) = (wi[2], wo[2]);
    match name {
        "lambert" => p("albedo") / PI,
        "mirror" => 0.0,
        "phong" => p("kd") / PI + p("ks") * pw(cos_alpha(wi, wo), p("n")),
        "lewis-phong" => {
            let n = p("n");
            p("kd") / PI + p("ks") * (n + 2.0) / (2.0 * PI) * pw(cos_alpha(wi, wo), n)
        }
        "blinn-phong" => {
            let n = p("n");
            let norm = (n + 2.0) * (n + 4.0) / (8.0 * PI * (2f64.powf(-n / 2.0) + n));
            p("kd") / PI + p("ks") * norm * pw(half(wi, wo)[2], n)
        }
        "cook-torrance" => {
            let (m, f0) = (p("m"), p("f0"));
            let h = half(wi, wo);
            let (c, u) = (h[2], dot(wi, h));
            let tan2 = (1.0 - c * c) / (c * c);
            let d = (-tan2 / (m * m)).exp() / (PI * m * m * c.powi(4));
            let g = 1f64.min(2.0 * c * co / u).min(2.0 * c * ci / u);
            let eta = (1.0 + f0.sqrt()) / (1.0 - f0.sqrt());
            let gg = (eta * eta + u * u - 1.0).sqrt();
            let f = 0.5
                * ((gg - u) / (gg + u)).powi(2)
                * (1.0 + ((u * (gg + u) - 1.0) / (u * (gg - u) + 1.0)).powi(2));
            p("kd") / PI + f * d * g / (4.0 * ci * co)
        }
        "oren-nayar" => {
            let (rho, s) = (p("albedo"), p("sigma"));
            let s2 = s * s;
            let (ti, to) = (ci.acos(), co.acos());
            let (a, b) = (ti.max(to), ti.min(to));
            let cd = cos_dphi(wi, wo);
            let c1 = 1.0 - 0.5 * s2 / (s2 + 0.33);
            let c2 = if cd >= 0.0 {
                0.45 * s2 / (s2 + 0.09) * a.sin()
            } else {
                0.45 * s2 / (s2 + 0.09) * (a.sin() - (2.0 * b / PI).powi(3))
            };
            let c3 = 0.125 * s2 / (s2 + 0.09) * (4.0 * a * b / (PI * PI)).powi(2);
            let f = rho / PI
                * (c1 + cd * c2 * b.tan() + (1.0 - cd.abs()) * c3 * ((a + b) / 2.0).tan())
                + 0.17 * rho * rho / PI * s2 / (s2 + 0.13) * (1.0 - cd * (2.0 * b / PI).powi(2));
            f.max(0.0)
        }
        "ward" => {
            let (ax, ay) = (p("alpha_x"), p("alpha_y"));
            let h = [wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]];
            let e = ((h[0] / ax).powi(2) + (h[1] / ay).powi(2)) / (h[2] * h[2]);
            p("kd") / PI + p("ks") * (-e).exp() / (4.0 * PI * ax * ay * (ci * co).sqrt())
        }
        "schlick" => {
            let (c, r, pp) = (p("c"), p("r"), p("p"));
            let h = half(wi, wo);
            let (u, t) = (dot(wi, h), h[2]);
            let s = c + (1.0 - c) * (1.0 - u).powi(5);
            let z = r / (1.0 + r * t * t - t * t).powi(2);
            let hl = h[0].hypot(h[1]);
            let w = if hl == 0.0 { 1.0 } else { h[0] / hl };
            let a = (pp / (pp * pp - pp * pp * w * w + w * w)).sqrt();
            s * z * a / (4.0 * PI * (r + (1.0 - r) * ci) * (r + (1.0 - r) * co))
        }
        "strauss" => {
            let (c, sm, mt, tr) = (
                p("color"),
                p("smoothness"),
                p("metalness"),
                p("transparency"),
            );
            let (kf, ks, k) = (1.12f64, 1.01f64, 0.1);
            let ff = |x: f64| {
                (1.0 / (x - kf).powi(2) - 1.0 / (kf * kf))
                    / (1.0 / (1.0 - kf).powi(2) - 1.0 / (kf * kf))
            };
            let gg = |x: f64| {
                (1.0 / (1.0 - ks).powi(2) - 1.0 / (x - ks).powi(2))
                    / (1.0 / (1.0 - ks).powi(2) - 1.0 / (ks * ks))
            };
            let angle = |w: V| w[0].hypot(w[1]).atan2(w[2]) / (PI / 2.0);
            let (xi, xo) = (angle(wi), angle(wo));
            let d = 1.0 - mt * sm;
            let rd = (1.0 - sm.powi(3)) * (1.0 - tr);
            let rn = (1.0 - tr) - rd;
            let j = ff(xi) * gg(xi) * gg(xo);
            let rj = (rn + (rn + k) * j).min(1.0);
            let cs = 1.0 + mt * (1.0 - ff(xi)) * (c - 1.0);
            c * d * rd / PI + cs * rj * pw(cos_alpha(wi, wo), 3.0 / (1.0 - sm)) / (PI * ci)
        }
        "htsg" => htsg(p, wi, wo),
        "poulin-fournier" => poulin_fournier(p, wi, wo),
        other => panic!("no reference for {other}"),
    }
}

/// erfc: 1 − (Maclaurin series of erf) below 3, Lentz's continued fraction above.
fn erfc(x: f64) -> f64 {
    if x < 0.0 {
        return 2.0 - erfc(-x);
    }
    if x < 3.0 {
        let (mut term, mut sum, mut k) = (x, x, 0.0);
        loop {
            k += 1.0;
            term *= -x * x / k;
            let add = term / (2.0 * k + 1.0);
            sum += add;
            if add.abs() < 1e-17 * sum.abs() {
                break;
            }
        }
        return 1.0 - 2.0 / PI.sqrt() * sum;
    }
    // erfc x = e^{-x²}/√π · 1/(x + (1/2)/(x + 1/(x + (3/2)/(x + ...)))).
    let mut f = x;
    let (mut c, mut d) = (x, 0.0);
    for n in 1..500 {
        let a = f64::from(n) / 2.0;
        d = 1.0 / (x + a * d);
        c = x + a / c;
        let delta = c * d;
        f *= delta;
        if (delta - 1.0).abs() < 1e-16 {
            break;
        }
    }
    (-x * x).exp() / (PI.sqrt() * f)
}

/// The w ≥ 0 with w e^w = y, by bisection.
fn lambert_w(y: f64) -> f64 {
    let (mut lo, mut hi) = (0.0f64, 1.0f64.max(y.ln_1p() + 1.0));
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mid * mid.exp() < y {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

fn htsg(p: &dyn Fn(&str) -> f64, wi: V, wo: V) -> f64 {
    let (s0, tau, lambda, eta, kappa) = (p("sigma0"), p("tau"), p("lambda"), p("eta"), p("kappa"));
    let (ci, co) = (wi[2], wo[2]);
    let tan = |w: V| w[0].hypot(w[1]) / w[2];
    let kk = |t: f64| {
        if t < 1e-6 {
            0.0
        } else {
            t * erfc(tau / (2.0 * s0 * t))
        }
    };
    let f0 = (kk(tan(wi)) + kk(tan(wo))) / (8.0 * PI).sqrt();
    let sigma = s0 / (1.0 + lambert_w(f0 * f0)).sqrt();
    let g = (2.0 * PI * sigma * (ci + co) / lambda).powi(2);
    let vxy = (wi[0] + wo[0]).powi(2) + (wi[1] + wo[1]).powi(2);
    let a = PI * PI * (tau / lambda).powi(2) * vxy;
    let sum = if g > 300.0 {
        let e = (-a / g).exp();
        e / g + g / 2.0 * e * (2.0 / g.powi(3) - 4.0 * a / g.powi(4) + a * a / g.powi(5))
    } else {
        let (mut sum, mut ln_fact, mut m) = (0.0, 0.0, 1.0f64);
        loop {
            ln_fact += m.ln();
            let t = (m * g.ln() - g - ln_fact - m.ln() - a / m).exp();
            sum += t;
            if m > g + 20.0 * g.sqrt() + 200.0 && t < 1e-18 * sum {
                break;
            }
            if m > 50_000.0 {
                break;
            }
            m += 1.0;
        }
        sum
    };
    let d = PI * PI * tau * tau / (4.0 * lambda * lambda) * sum;
    let c = dot(wi, wo);
    let geo = ((2.0 + 2.0 * c) / (ci + co)).powi(2);
    let shadow = |w: V| {
        let st = w[0].hypot(w[1]);
        if st == 0.0 {
            return 1.0;
        }
        let a = tau * w[2] / st / (2.0 * s0);
        let lam = 0.5 * ((-a * a).exp() / (a * PI.sqrt()) - erfc(a));
        (1.0 - 0.5 * erfc(a)) / (lam + 1.0)
    };
    let s = shadow(wi) * shadow(wo);
    let cl = ((1.0 + c) / 2.0).sqrt();
    let fresnel = if cl < 1e-7 {
        1.0
    } else {
        let s2 = 1.0 - cl * cl;
        let t = s2.sqrt() / cl;
        let b = eta * eta - kappa * kappa - s2;
        let q = (b * b + 4.0 * eta * eta * kappa * kappa).sqrt();
        let (a2, b2) = ((q + b) / 2.0, (q - b) / 2.0);
        let aa = a2.sqrt();
        let fs = (a2 + b2 - 2.0 * aa * cl + cl * cl) / (a2 + b2 + 2.0 * aa * cl + cl * cl);
        let fp = fs * (a2 + b2 - 2.0 * aa * s2.sqrt() * t + s2 * t * t)
            / (a2 + b2 + 2.0 * aa * s2.sqrt() * t + s2 * t * t);
        (fs + fp) / 2.0
    };
    fresnel * geo * s * d / (PI * ci * co) + p("a") / PI
}

/// Adaptive Simpson on [a, b] to a relative tolerance (of a 33-point first estimate).
fn simpson(f: &dyn Fn(f64) -> f64, a: f64, b: f64, rel: f64) -> f64 {
    /// One panel [a, b] with f at a, the midpoint and b, its Simpson value `whole`.
    fn rec(
        f: &dyn Fn(f64) -> f64,
        ab: [f64; 2],
        fs: [f64; 3],
        whole: f64,
        tol: f64,
        depth: u32,
    ) -> f64 {
        let ([a, b], [fa, fm, fb]) = (ab, fs);
        let m = 0.5 * (a + b);
        let (flm, frm) = (f(0.5 * (a + m)), f(0.5 * (m + b)));
        let left = (m - a) / 6.0 * (fa + 4.0 * flm + fm);
        let right = (b - m) / 6.0 * (fm + 4.0 * frm + fb);
        let diff = left + right - whole;
        if depth == 0 || (diff.abs() <= 15.0 * tol && depth < 36) {
            return left + right + diff / 15.0;
        }
        rec(f, [a, m], [fa, flm, fm], left, tol / 2.0, depth - 1)
            + rec(f, [m, b], [fm, frm, fb], right, tol / 2.0, depth - 1)
    }
    let scale: f64 = (0..=32)
        .map(|k| f(a + (b - a) * f64::from(k) / 32.0).abs())
        .sum::<f64>()
        * (b - a)
        / 33.0;
    let tol = (rel * scale).max(1e-300);
    let (fa, fm, fb) = (f(a), f(0.5 * (a + b)), f(b));
    let whole = (b - a) / 6.0 * (fa + 4.0 * fm + fb);
    rec(f, [a, b], [fa, fm, fb], whole, tol, 40)
}

/// Whether the 2D ray from `p` toward (dy, dz) hits the material of a cylinder centred at
/// (cy, h − 1) (radius 1, only the part at z ≥ 0 exists).
fn ray_hits_circle(p: (f64, f64), d: (f64, f64), cy: f64, h: f64) -> bool {
    let (ox, oz) = (p.0 - cy, p.1 - (h - 1.0));
    let a = d.0 * d.0 + d.1 * d.1;
    let b = 2.0 * (ox * d.0 + oz * d.1);
    let c = ox * ox + oz * oz - 1.0;
    let disc = b * b - 4.0 * a * c;
    if disc < 0.0 {
        return false;
    }
    let r = disc.sqrt();
    [(-b - r) / (2.0 * a), (-b + r) / (2.0 * a)]
        .iter()
        .any(|&t| t > 1e-12 && p.1 + t * d.1 >= 0.0)
}

/// The sub-intervals of [lo, hi] where `vis` holds: a grid of `n` points, each change refined
/// by bisection.
fn visible_set(vis: &dyn Fn(f64) -> bool, lo: f64, hi: f64, n: usize) -> Vec<(f64, f64)> {
    let x = |k: usize| lo + (hi - lo) * k as f64 / n as f64;
    let edge = |mut a: f64, mut b: f64| {
        let va = vis(a);
        for _ in 0..100 {
            let m = 0.5 * (a + b);
            if vis(m) == va { a = m } else { b = m }
        }
        0.5 * (a + b)
    };
    let mut out = Vec::new();
    let mut start = if vis(lo) { Some(lo) } else { None };
    let mut prev = vis(lo);
    for k in 1..=n {
        let v = vis(x(k));
        if v != prev {
            let e = edge(x(k - 1), x(k));
            if v {
                start = Some(e);
            } else if let Some(s) = start.take() {
                out.push((s, e));
            }
            prev = v;
        }
    }
    if let Some(s) = start {
        out.push((s, hi));
    }
    out
}

fn intersect(a: &[(f64, f64)], b: &[(f64, f64)]) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    for &(a0, a1) in a {
        for &(b0, b1) in b {
            let (lo, hi) = (a0.max(b0), a1.min(b1));
            if hi > lo {
                out.push((lo, hi));
            }
        }
    }
    out
}

fn poulin_fournier(p: &dyn Fn(&str) -> f64, wi: V, wo: V) -> f64 {
    let (h, gap, kd, ks, n) = (p("height"), p("gap"), p("kd"), p("ks"), p("n"));
    let pm = (1.0 - h).acos();
    let w = pm.sin();
    let period = 2.0 * w + gap;
    let blocked = |pt: (f64, f64), dir: V, skip_own: bool| {
        (-2..=2).any(|k: i32| {
            !(skip_own && k == 0) && ray_hits_circle(pt, (dir[1], dir[2]), f64::from(k) * period, h)
        })
    };
    let normal = |phi: f64| [0.0, phi.sin(), phi.cos()];
    let on_cyl = |phi: f64| (phi.sin(), h - 1.0 + phi.cos());
    let lit_cyl =
        |dir: V| move |phi: f64| dot(normal(phi), dir) > 0.0 && !blocked(on_cyl(phi), dir, true);
    let lit_gap = |dir: V| move |y: f64| !blocked((y, 0.0), dir, false);
    let local = |nn: V| {
        let c = 2.0 * dot(nn, wi) * dot(nn, wo) - dot(wi, wo);
        kd / PI + ks * (n + 2.0) / (2.0 * PI) * pw(c.max(0.0), n)
    };
    let grid = 20_000;
    let mut total = 0.0;
    let cyl = intersect(
        &visible_set(&lit_cyl(wi), -pm, pm, grid),
        &visible_set(&lit_cyl(wo), -pm, pm, grid),
    );
    for (a, b) in cyl {
        let f = |phi: f64| {
            let nn = normal(phi);
            local(nn) * dot(nn, wi).max(0.0) * dot(nn, wo).max(0.0)
        };
        total += simpson(&f, a, b, 1e-10);
    }
    if gap > 0.0 {
        let g = intersect(
            &visible_set(&lit_gap(wi), w, period - w, grid),
            &visible_set(&lit_gap(wo), w, period - w, grid),
        );
        let len: f64 = g.iter().map(|(a, b)| b - a).sum();
        total += wi[2] * wo[2] * local([0.0, 0.0, 1.0]) * len;
    }
    total / (period * wi[2] * wo[2])
}
