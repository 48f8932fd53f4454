//! An independent f64 evaluation of MODELS.md's nine formulas, written from the document and
//! sharing no code with the library: the oracle `brdf eval` is checked against.

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
        other => panic!("no reference for {other}"),
    }
}
