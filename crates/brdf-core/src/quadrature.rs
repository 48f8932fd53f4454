//! Deterministic numerical integration in f64: Gauss–Legendre rules and composite hemisphere
//! integrals. These are the *independent* integrators: tests use them as oracles, never the
//! quadtree.

use crate::brdf::Brdf;
use crate::math as m;
use alloc::vec::Vec;
use core::f64::consts::{FRAC_PI_2, PI};
use core::ops::{AddAssign, Mul};
use glam::{DVec3, Vec3};

/// An n-point Gauss–Legendre rule on [−1, 1]: exact for polynomials of degree 2n − 1.
#[derive(Clone, Debug, PartialEq)]
pub struct GaussLegendre {
    nodes: Vec<f64>,
    weights: Vec<f64>,
}

impl GaussLegendre {
    /// Builds the rule by Newton iteration on P_n (converged to machine precision).
    /// `n` is clamped to at least 1.
    #[must_use]
    pub fn new(n: usize) -> Self {
        let n = n.max(1);
        let mut nodes = Vec::with_capacity(n);
        let mut weights = Vec::with_capacity(n);
        for i in 0..n {
            // Tricomi's initial guess for the i-th root, descending from 1.
            let mut x = m::cos(PI * (i as f64 + 0.75) / (n as f64 + 0.5));
            let mut dp = 1.0;
            for _ in 0..100 {
                let (p, d) = legendre(n, x);
                dp = d;
                let dx = p / d;
                x -= dx;
                if dx.abs() < 1e-16 {
                    break;
                }
            }
            let (_, d) = legendre(n, x);
            dp = if d != 0.0 { d } else { dp };
            nodes.push(x);
            weights.push(2.0 / ((1.0 - x * x) * dp * dp));
        }
        Self { nodes, weights }
    }

    /// The rule's nodes on [−1, 1].
    #[must_use]
    pub fn nodes(&self) -> &[f64] {
        &self.nodes
    }

    /// The rule's weights (they sum to 2).
    #[must_use]
    pub fn weights(&self) -> &[f64] {
        &self.weights
    }

    /// (node, weight) pairs mapped onto [a, b].
    pub fn on(&self, a: f64, b: f64) -> impl Iterator<Item = (f64, f64)> + '_ {
        let (c, h) = (0.5 * (a + b), 0.5 * (b - a));
        self.nodes
            .iter()
            .zip(&self.weights)
            .map(move |(&x, &w)| (c + h * x, h * w))
    }

    /// ∫_a^b f(x) dx with this rule.
    pub fn integrate(&self, a: f64, b: f64, mut f: impl FnMut(f64) -> f64) -> f64 {
        self.on(a, b).map(|(x, w)| w * f(x)).sum()
    }
}

/// P_n(x) and P_n'(x) by the three-term recurrence.
fn legendre(n: usize, x: f64) -> (f64, f64) {
    let (mut p0, mut p1) = (1.0, x);
    for k in 2..=n {
        let k = k as f64;
        let p2 = ((2.0 * k - 1.0) * x * p1 - (k - 1.0) * p0) / k;
        p0 = p1;
        p1 = p2;
    }
    if n == 0 {
        return (1.0, 0.0);
    }
    let d = n as f64 * (x * p1 - p0) / (x * x - 1.0);
    (p1, d)
}

/// ∫ f(ω) dω over the upper hemisphere (per unit solid angle), by a composite Gauss–Legendre
/// product rule in (θ, φ): `panels` panels in θ ∈ [0, π/2] and 4·`panels` in φ, `order` points
/// each. The horizon is a boundary of the domain, so integrands cut off there converge fast.
pub fn hemisphere_integral<T>(panels: usize, order: usize, f: impl Fn(Vec3) -> T) -> T
where
    T: Default + AddAssign + Mul<f64, Output = T>,
{
    let rule = GaussLegendre::new(order);
    let panels = panels.max(1);
    let (dt, dp) = (FRAC_PI_2 / panels as f64, 2.0 * PI / (4 * panels) as f64);
    let mut total = T::default();
    for i in 0..panels {
        for (theta, wt) in rule.on(i as f64 * dt, (i + 1) as f64 * dt) {
            let (st, ct) = (m::sin(theta), m::cos(theta));
            for j in 0..4 * panels {
                for (phi, wp) in rule.on(j as f64 * dp, (j + 1) as f64 * dp) {
                    let w = DVec3::new(st * m::cos(phi), st * m::sin(phi), ct).as_vec3();
                    total += f(w) * (wt * wp * st);
                }
            }
        }
    }
    total
}

/// The directional albedo ρ(wi) = ∫ f_r(wi, wo) cos θo dωo of a BRDF's continuous part, RGB,
/// by [`hemisphere_integral`] (see there for `panels` and `order`).
pub fn directional_albedo<B: Brdf + ?Sized>(
    brdf: &B,
    wi: Vec3,
    panels: usize,
    order: usize,
) -> DVec3 {
    hemisphere_integral(panels, order, |wo| {
        brdf.eval(wi, wo).as_dvec3() * f64::from(wo.z)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gauss_legendre_is_exact_for_polynomials() {
        for n in [1, 2, 5, 12, 40] {
            let r = GaussLegendre::new(n);
            assert!((r.weights().iter().sum::<f64>() - 2.0).abs() < 1e-13);
            let deg = 2 * n - 1;
            let exact = |k: usize| {
                if k % 2 == 1 {
                    0.0
                } else {
                    2.0 / (k as f64 + 1.0)
                }
            };
            for k in 0..=deg {
                let got = r.integrate(-1.0, 1.0, |x| x.powi(k as i32));
                assert!((got - exact(k)).abs() < 1e-12, "n={n} k={k}: {got}");
            }
        }
        // A published value: the 3-point rule's nodes are 0, ±√(3/5) with weights 8/9, 5/9.
        let r = GaussLegendre::new(3);
        let mut nodes: Vec<f64> = r.nodes().to_vec();
        nodes.sort_by(f64::total_cmp);
        assert!((nodes[2] - (0.6f64).sqrt()).abs() < 1e-15 && nodes[1].abs() < 1e-15);
    }

    #[test]
    fn hemisphere_integrals_of_known_functions() {
        let area = hemisphere_integral(8, 4, |_| 1.0);
        assert!((area - 2.0 * PI).abs() < 1e-12);
        let cos = hemisphere_integral(8, 4, |w| f64::from(w.z));
        assert!((cos - PI).abs() < 1e-6);
        let x2 = hemisphere_integral(8, 4, |w| f64::from(w.x * w.x));
        assert!((x2 - 2.0 * PI / 3.0).abs() < 1e-6);
    }
}
