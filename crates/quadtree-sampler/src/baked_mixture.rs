//! How a [`BakedSampler`] answers at a wi off its grid: an exact mixture of the
//! neighbouring grid trees.
//!
//! `wi` is first folded into the grid's domain by its symmetries (a rotation about z, or
//! reflections in x and y: both preserve solid angle and f_r). Its neighbouring grid trees k
//! get interpolation weights w_k (linear in θi; in (θi, φi) linear on the triangle of the
//! cell that holds wi, three trees at most; in rejection mode, in a cell where the bake
//! measured that neighbouring trees sample each other's densities as well as their own,
//! the nearer tree along that axis takes the whole weight: one model evaluation fewer a
//! sample and a pdf, see `baked_nearest`). A sharp lobe moves
//! with `wi` faster than any affordable grid follows, so each neighbour is not used as is:
//! its directions are **rotated by the rotation R_k that carries the grid direction's mirror
//! r(wi_k) onto r(wi)** — the lobe of tree k then sits where the lobe of `wi` is. A rotation
//! has Jacobian 1, so component k's density at `wo` is exactly p_k(R_k⁻¹ wo) (0 where
//! R_k⁻¹ wo is below the horizon: such samples are lost, never re-drawn). The tilt leaves a
//! band above the horizon that tree k does not reach; the neighbour on the other side,
//! tilted the other way, covers it, and beyond the last row, where there is none, the last
//! tree enters twice: rotated, and untilted (R_k about z alone), the second with the share
//! a row one spacing further on would take (a spacing no wider than the default grid's, so
//! that a coarse grid does not starve the band). With a defensive share δ of cosine sampling,
//! which keeps the density positive wherever f_r·cos θ is,
//!
//! pdf(wi, wo) = δ·cos θo/π + (1 − δ)·Σ_k w_k·p_k(R_k⁻¹ wo)  (per unit solid angle),
//!
//! On an anisotropic grid a rotation is not enough: a lobe narrow along one tangent axis
//! (Ward αx = 0.01, αy = 0.5) is a thin curved sheet whose curvature changes with wi, and
//! a rotation matches it near the mirror direction only (the weight's R, `baked_coverage`,
//! reached 10⁴ at θi = 45° and 10⁷ at 80° on the default grid). There each neighbour is
//! carried by the **half-vector transport** instead ([`HalfMap`]): a tree direction w goes
//! where wi reflects about w's half vector with the tree's incident direction, which leaves
//! any function of the half vector (a microfacet lobe) in place; the density gains the
//! Jacobian ratio (wi_k·h)/(wi·h), and the same sum holds with that map and factor. (R then
//! stays at most 1.64 in rejection mode and 1.73 in warp mode on that material's default
//! grid; on the bench sets it is as good as the rotation or better: poulin-fournier
//! n = 1000 1.44 → 1.09.) The untilted copies beyond the last row stay rotations.
//!
//! and that is what `sample` draws: `uc` picks the defensive part or neighbour k, `u` drives
//! the chosen tree, the result is rotated by R_k and unfolded. The reported pdf is the true
//! density of what was drawn, so f·cos θo/pdf is unbiased and the pdf is fit for multiple
//! importance sampling at any (wi, wo). With p_k:
//! - **rejection**: Y(f_r(wi_k, w))·cos θ·J/V_k, tree k's own density (exact up to its leaf
//!   integrals, as for [`crate::QuadtreeSampler`]); `u` descends the tree, the rejection trials
//!   draw from an RNG; one model evaluation per neighbour for the pdf (a sample's own
//!   neighbour reuses its accepted trial's, made at the very point the pdf looks at);
//! - **warp**: tree k's proxy (each leaf's share of the volume spread over its square,
//!   uniformly or by the shape fitted to f there), a deterministic function of (uc, u) —
//!   stratified and low-discrepancy points stay stratified — and its pdf is a table look-up
//!   per neighbour, without evaluating the model (the neighbour that drew a sample reads its
//!   leaf's density at the point without a look-up while the sample's direction maps back
//!   into that leaf).
//!
//! A model that declares f_r independent of wi ([`brdf_core::Brdf::independent_of_incident`]:
//! Lambert, a Phong with ks = 0 or n = 0, Oren–Nayar at σ = 0) has the same density in every
//! tree, that of a tree built at any query's own wi: there its first tree is the only
//! component, weight 1, not rotated.

use crate::bake_grid::{
    Nearest, PhiDomain, isotropic_to_local, rotation_arc, rotation_between_mirrors_xz,
};
use crate::baked::{BakedMode, BakedSampler, Role, Tables};
use crate::sampler::{DensityHints, Ridge, Sample, rejection_in_leaf};
use crate::warp_table::WarpLeaf;
use brdf_core::geometry::{above_horizon, lift_incident, luminance, normalize_f64};
use brdf_core::math as m;
use brdf_core::warp::sample_cosine_hemisphere;
use core::sync::atomic::Ordering;
use glam::{DMat3, DVec3, Vec2, Vec3};
use rand_core::Rng;

/// What the draw of a sample knows of its own component's density.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Drawn {
    /// Warp mode: the leaf it was drawn in. Its density is the one [`WarpTable::density`]
    /// finds wherever the direction maps back into that leaf (the same stored number), so
    /// only a point that rounding moved out of it descends.
    Warp(WarpLeaf),
    /// Rejection mode: the density itself, from the accepted trial's evaluation at the very
    /// point `component_pdf` evaluates.
    Density(f64),
}

/// `v` normalised (0 for a zero, infinite or NaN `v`), a deterministic function of its bits
/// that `pdf` and the pdf a sample carries share: [`normalize_f64`] (two multiply-adds for
/// the near-unit vectors samples and callers pass, instead of a square root and a division on
/// the sample's critical path), guarded so that a degenerate `v` gives 0 rather than NaN.
#[inline(always)]
fn near_unit(v: DVec3) -> DVec3 {
    let l2 = v.length_squared();
    if l2 > 0.0 && l2.is_finite() {
        normalize_f64(v)
    } else {
        DVec3::ZERO
    }
}

/// No nearest-tree cells: every neighbour blends (warp mode).
static BLEND: Nearest = Nearest {
    theta: alloc::vec::Vec::new(),
    phi: alloc::vec::Vec::new(),
};

/// A query's mixture components, on the stack: at most two neighbours along θi, three on a
/// cell's triangle in (θi, φi), or the last row's up to two trees twice beyond it. (Not an
/// array of placeholders: four of those, 168 bytes each, were copied in on every sample and
/// pdf.)
pub(crate) type Components = arrayvec::ArrayVec<Component, 4>;

/// What every answer at one given direction shares, found once: the role, the checked
/// direction, the mode and the mixture's components there. A [`crate::BakedPoint`] keeps one
/// for all its answers (a path vertex samples, evaluates and asks the pdf at the same
/// direction); the per-call `sample` and `pdf` find the same components on their own stack
/// and hand them to the same code ([`BakedSampler::pdf_of`], `sample_from`).
#[derive(Clone, Debug)]
pub(crate) struct Query {
    pub(crate) role: Role,
    pub(crate) given: Vec3,
    pub(crate) mode: BakedMode,
    pub(crate) comps: Components,
}

/// One neighbour of a query: its tree, weight, and the map from its tree's frame to the
/// caller's local frame: unfold ∘ rotation onto the query's mirror direction (`to_local`),
/// or, where `half` is set, the half-vector transport (see [`HalfMap`]; `to_local` then
/// only places the tree's peak hints).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Component {
    pub(crate) slice: usize,
    pub(crate) weight: f64,
    pub(crate) to_local: DMat3,
    pub(crate) half: Option<HalfMap>,
}

/// The half-vector transport of a tree's directions onto a query (anisotropic bakes): a
/// direction w of the tree (built at incident direction k) has the half vector
/// h = (k + w)/|k + w|, and goes to the direction the query's incident g reflects about the
/// same h, 2(g·h)h − g. A microfacet lobe is a function of h (Ward's, Cook–Torrance's), so
/// this carries a neighbour's lobe onto the query's own lobe however its shape changes with
/// g, where a rotation onto the query's mirror direction only matches it near the mirror:
/// Ward αx = 0.01, αy = 0.5 on the default grid had a weight whose second moment over its
/// squared mean (R, `baked_coverage`) reached 10⁴ at θi = 45° and 10⁷ at 80° under
/// rotations, and stays at most 1.64 (rejection) and 1.73 (warp) under this map. The map is
/// a bijection (h ↦ 2(g·h)h − g is one from {g·h > 0} to the sphere less −g), and the
/// density gains the ratio of the two Jacobians dω/dω_h = 4(g·h):
/// p(wo) = p_tree(w)·(k·h)/(g·h). A tree direction whose h has g·h ≤ 0, or that lands below
/// the horizon, is lost (like a rotated one).
#[derive(Clone, Copy, Debug)]
pub(crate) struct HalfMap {
    /// The tree's incident direction, unit, in the folded frame.
    pub(crate) tree: DVec3,
    /// The query's incident direction, unit, folded.
    pub(crate) given: DVec3,
    /// Folded → local (the fold's inverse: reflection signs on the diagonal).
    pub(crate) unfold: DVec3,
}

/// The rotation arc from mirror direction `from` onto `to` (both folded), then unfolded by
/// the domain's reflection signs: an anisotropic grid tree's frame → local.
#[inline(always)]
fn rotation_onto(from: DVec3, to: DVec3, unfold: DVec3) -> DMat3 {
    let r = rotation_arc(from, to);
    DMat3::from_cols(r.x_axis * unfold, r.y_axis * unfold, r.z_axis * unfold)
}

impl HalfMap {
    /// A tree direction `w` (unit) in the local frame, or `None` where it is lost. With
    /// s = k + w (the half vector unnormalised), the reflection is 2(g·s)/(s·s)·s − g: one
    /// division, no square root.
    #[inline(always)]
    pub(crate) fn forward(&self, w: DVec3) -> Option<DVec3> {
        let s = self.tree + w;
        let gs = self.given.dot(s);
        (gs > 0.0).then(|| ((2.0 * gs / s.length_squared()) * s - self.given) * self.unfold)
    }

    /// The tree direction a local unit `wo` comes from and the density's Jacobian factor
    /// (k·h)/(g·h), or `None` where no tree direction maps to it. With s = g + wo, the
    /// direction is 2(k·s)/(s·s)·s − k and the factor (k·s)/(g·s): both from one reciprocal.
    #[inline(always)]
    pub(crate) fn back(&self, wo: DVec3) -> Option<(DVec3, f64)> {
        let s = self.given + wo * self.unfold;
        let (ks, gs, ss) = (self.tree.dot(s), self.given.dot(s), s.length_squared());
        if !(ks > 0.0 && gs > 0.0) {
            return None;
        }
        let inv = 1.0 / (gs * ss);
        Some(((2.0 * ks * gs * inv) * s - self.tree, ks * ss * inv))
    }
}

impl Component {
    /// A direction of this component's tree (unit) in the local frame, as a sample returns
    /// it; 0 (below every horizon) where the half-vector transport loses it.
    #[inline(always)]
    fn carry(&self, w: DVec3) -> Vec3 {
        match &self.half {
            None => (self.to_local * w).as_vec3(),
            Some(m) => m.forward(w).map_or(Vec3::ZERO, DVec3::as_vec3),
        }
    }

    /// The tree direction a local unit `wo` comes from, with the density's Jacobian factor
    /// (1 for a rotation), or `None` where none does.
    #[inline(always)]
    fn back(&self, wo: DVec3) -> Option<(DVec3, f64)> {
        match &self.half {
            None => Some((self.to_local.transpose() * wo, 1.0)),
            Some(m) => m.back(wo),
        }
    }
}

impl BakedSampler {
    pub(crate) fn tables_for(&self, role: Role) -> (&Tables, bool) {
        match (role, &self.adjoint) {
            (Role::Radiance, Some(adj)) => (adj, true),
            _ => (&self.forward, false),
        }
    }

    /// f of a grid tree's model at (its wi, w): the model, or its adjoint.
    #[inline]
    pub(crate) fn table_eval(&self, adjoint: bool, wi: Vec3, w: Vec3) -> Vec3 {
        if adjoint {
            self.brdf.eval(w, wi)
        } else {
            self.brdf.eval(wi, w)
        }
    }

    /// The components of the mixture at a given (checked, unit) direction: pushed onto `out`
    /// (empty, the caller's, so that they are not copied on their way back), their number
    /// returned.
    #[inline(always)]
    pub(crate) fn components(
        &self,
        mode: BakedMode,
        tables: &Tables,
        given: Vec3,
        out: &mut Components,
    ) -> usize {
        debug_assert!(out.is_empty());
        // A model whose f_r is the same at every wi: every forward tree holds one density,
        // that of a tree built at `given` itself, so the first tree serves as it is (no
        // neighbours, no rotation, nothing lost below the horizon). A non-reciprocal
        // model's adjoint trees blend as usual: the promise is about f_r's first argument.
        if self.one_tree && core::ptr::eq(tables, &self.forward) {
            if tables.slices.first().is_some_and(|s| s.live) {
                out.push(Component {
                    slice: 0,
                    weight: 1.0,
                    to_local: DMat3::IDENTITY,
                    half: None,
                });
            }
            return out.len();
        }
        let g = given.as_dvec3();
        let mut sum = 0.0;
        // Isotropic: fold by the rotation about z by −φ (from cos φ and sin φ without
        // trigonometry) onto (sin θ, 0, cos θ); each neighbour's map to the local frame is the
        // rotation about y between the two mirrors, then about z back by φ, written out.
        // Otherwise: the domain's fold, and the rotation arc between the mirrors.
        let iso = self.grid.domain() == PhiDomain::Rotation;
        let (gc, cs, unfold, mc) = if iso {
            // 1/r as r·(1/r²): the division and the square root run side by side instead of
            // one after the other (each some 15 cycles, on every `sample`'s and `pdf`'s
            // critical path). `given` is a unit f32 vector, so r² is 0 or at least
            // (1.4·10⁻⁴⁵)² ≈ 2·10⁻⁹⁰, and 1/r² finite.
            let r2 = g.x * g.x + g.y * g.y;
            let r = m::sqrt(r2);
            let cs = if r2 > 0.0 {
                let inv = r * (1.0 / r2);
                (g.x * inv, g.y * inv)
            } else {
                (1.0, 0.0)
            };
            (DVec3::new(r, 0.0, g.z), cs, DVec3::ONE, DVec3::Z)
        } else {
            // The fold is a reflection (diagonal ±1, its own inverse): unfolding a matrix
            // scales its rows, not a matrix product.
            let signs = self.grid.domain().reflection(g);
            let gc = g * signs;
            let mc = DVec3::new(-gc.x, -gc.y, gc.z).normalize();
            (gc, (1.0, 0.0), signs, mc)
        };
        let nearest = match mode {
            BakedMode::Rejection => &tables.nearest,
            BakedMode::Warp => &BLEND,
        };
        for (slice, w) in self.grid.neighbours(gc, nearest) {
            if w <= 0.0 || !tables.slices[slice].live {
                continue;
            }
            if let Some(c) = out.iter_mut().find(|c| c.slice == slice) {
                c.weight += w;
                sum += w;
                continue;
            }
            let half = (self.half_vector && !iso).then(|| {
                let mk = tables.slices[slice].mirror;
                HalfMap {
                    tree: DVec3::new(-mk.x, -mk.y, mk.z),
                    given: gc,
                    unfold,
                }
            });
            // (A half-vector component's rotation only places peak hints: made there.)
            let to_local = if iso {
                let wk = tables.slices[slice].wi.as_dvec3();
                isotropic_to_local(cs, rotation_between_mirrors_xz(wk, gc))
            } else if half.is_some() {
                DMat3::IDENTITY
            } else {
                rotation_onto(tables.slices[slice].mirror, mc, unfold)
            };
            out.push(Component {
                slice,
                weight: w,
                to_local,
                half,
            });
            sum += w;
        }
        if sum != 1.0 && !out.is_empty() {
            let inv = 1.0 / sum;
            for c in out.iter_mut() {
                c.weight *= inv;
            }
        }
        // Beyond the last row (θ up to the horizon) the last row's trees are its only
        // neighbours, and rotating one onto `given`'s mirror tilts its hemisphere: a band
        // above the horizon on the side toward `given` is left that no tree draws from (only
        // the defensive share: Oren–Nayar at 89.9°, whose retro-reflection lies there, gave a
        // mean weight 0.28 % under its albedo, 24 standard errors at 10⁶ samples). Within the
        // grid the next row's tree, tilted the other way, covers it. Here the tree itself
        // stands in for that missing row: untilted (turned about z only, onto `given`'s
        // azimuth), with the share linear interpolation would give a row one spacing on (at
        // most the default grid's spacing: see `beyond_last_row`).
        let beyond = self.grid.beyond_last_row(gc);
        // (Beyond the last row only that row has weight: at most two components, doubled.)
        let n = out.len();
        if beyond > 0.0 && n <= 2 {
            for k in 0..n {
                let c = out[k];
                let to_local = if iso {
                    isotropic_to_local(cs, (1.0, 0.0))
                } else {
                    let mk = tables.slices[c.slice].mirror;
                    let r = rotation_arc(
                        DVec3::new(mk.x, mk.y, 0.0).normalize(),
                        DVec3::new(mc.x, mc.y, 0.0).normalize(),
                    );
                    DMat3::from_cols(r.x_axis * unfold, r.y_axis * unfold, r.z_axis * unfold)
                };
                out[k].weight = c.weight * (1.0 - beyond);
                out.push(Component {
                    slice: c.slice,
                    weight: c.weight * beyond,
                    to_local,
                    half: None,
                });
            }
        }
        out.len()
    }

    /// Component `c`'s density at local `wo`, per unit solid angle. `drawn`: what the draw
    /// of the sample being scored already knows, when `c` is the component that drew it
    /// (see [`Drawn`]); it changes how the density is found, never its value.
    #[inline]
    pub(crate) fn component_pdf(
        &self,
        mode: BakedMode,
        tables: &Tables,
        adjoint: bool,
        c: &Component,
        wo: DVec3,
        drawn: Option<&Drawn>,
    ) -> f64 {
        if let Some(&Drawn::Density(d)) = drawn {
            return d;
        }
        let Some((w, jacobian)) = c.back(wo) else {
            return 0.0;
        };
        if w.z <= 0.0 {
            return 0.0;
        }
        let s = &tables.slices[c.slice];
        jacobian
            * match mode {
                BakedMode::Rejection => {
                    let y = f64::from(luminance(self.table_eval(adjoint, s.wi, w.as_vec3())));
                    y * w.z * s.rejection_scale
                }
                BakedMode::Warp => {
                    // In f64, from the unit f64 direction: the f32 map cannot place a point of
                    // the rim band (see the per-wi warp's `square_point`).
                    let p = s.map.direction_to_square_f64(w);
                    let d = match drawn {
                        Some(Drawn::Warp(l)) if l.contains(p) => l.density_at(p, w.z),
                        _ => s.warp.density(p, w.z),
                    };
                    d * s.warp_scale * w.z
                }
            }
    }

    /// The density of [`BakedSampler::sample_continuous_as`] at a checked pair. `sampled`
    /// need only be finite and non-zero: it is normalised here in f64, so that the pdf a
    /// sample carries and the pdf of the same f32 vector asked for later are bit-identical
    /// (renormalising in f32 could move a direction on a leaf's edge into its neighbour).
    pub(crate) fn pdf_unit(&self, role: Role, given: Vec3, sampled: Vec3) -> f32 {
        self.pdf_unit_in(self.mode, role, given, sampled)
    }

    /// [`BakedSampler::pdf_unit`] in `mode`, whichever mode the sampler is set to.
    pub(crate) fn pdf_unit_in(
        &self,
        mode: BakedMode,
        role: Role,
        given: Vec3,
        sampled: Vec3,
    ) -> f32 {
        let (tables, adjoint) = self.tables_for(role);
        let mut comps = Components::new();
        let n = self.components(mode, tables, given, &mut comps);
        self.pdf_of(mode, tables, adjoint, &comps[..n], sampled, None)
    }

    /// The [`Query`] at a checked `given` for a role in `mode`. Inlined, so that the point
    /// [`BakedSampler::point`] returns is built where its caller keeps it: called, its
    /// some 680 bytes were copied on their way back (a sample through a point cost 50 ns
    /// more than `sample_as`; inlined, 6 ns). The per-call paths keep their components on
    /// their own stack for the same reason (built here and moved, 15 ns a sample).
    #[inline(always)]
    pub(crate) fn query(&self, mode: BakedMode, role: Role, given: Vec3) -> Query {
        let (tables, _) = self.tables_for(role);
        let mut comps = Components::new();
        self.components(mode, tables, given, &mut comps);
        Query {
            role,
            given,
            mode,
            comps,
        }
    }

    /// [`BakedSampler::pdf_unit`] from a [`Query`] made by this sampler.
    pub(crate) fn query_pdf(&self, q: &Query, sampled: Vec3) -> f32 {
        let (tables, adjoint) = self.tables_for(q.role);
        self.pdf_of(q.mode, tables, adjoint, &q.comps, sampled, None)
    }

    /// [`BakedSampler::sample_unit`] from a [`Query`] made by this sampler.
    pub(crate) fn query_sample<R: Rng + ?Sized>(
        &self,
        q: &Query,
        uc: f32,
        u: Vec2,
        rng: &mut R,
    ) -> Option<Sample> {
        self.sample_from(q.mode, q.role, q.given, &q.comps, uc, u, rng)
    }

    /// Where the mixture's density at a checked `given` may be concentrated (see
    /// [`crate::DirectionSampler::density_hints`]): each neighbour tree's peaks (the
    /// model's hints at the tree's direction) and their axis planes x = h.x and y = h.y,
    /// carried to the local frame by the component's rotation. A lobe narrow along one axis
    /// of its tree (Ward's as αx → 0) lies along such a rotated plane, which the model's
    /// own hints at `given` do not name.
    pub(crate) fn density_hints_unit(&self, role: Role, given: Vec3) -> DensityHints {
        let (tables, _) = self.tables_for(role);
        let mut comps = Components::new();
        let n = self.components(self.mode, tables, given, &mut comps);
        // In rejection mode its densities follow the model's f: a staircase where the model
        // is one. (The warp's are constant on the trees' leaves: cut finer, no harm done.)
        let mut hints = DensityHints {
            step: self.brdf.step_width(),
            ..DensityHints::default()
        };
        for c in &comps[..n] {
            let s = &tables.slices[c.slice];
            // A half-vector component carries its peaks by its own map, and its axis planes
            // as the rotation onto the query's mirror would (near its lobe the two agree).
            let rotation = match &c.half {
                None => c.to_local,
                Some(m) => {
                    let g = m.given;
                    rotation_onto(s.mirror, DVec3::new(-g.x, -g.y, g.z).normalize(), m.unfold)
                }
            };
            for h in self.brdf.peak_hints(lift_incident(s.wi)).as_slice() {
                let h = h.as_dvec3();
                hints.peaks.push(match &c.half {
                    None => rotation * h,
                    Some(m) => m.forward(h).unwrap_or(rotation * h),
                });
                for (axis, offset) in [(DVec3::X, h.x), (DVec3::Y, h.y)] {
                    hints.ridges.push(Ridge {
                        normal: rotation * axis,
                        offset,
                    });
                }
            }
        }
        hints
    }

    /// The mixture's density at `sampled` from its components (the one expression behind
    /// `pdf` and the pdf a sample carries; `drawn`: the component a sample came from and what
    /// its draw knows, which changes how its density is found, never its value).
    pub(crate) fn pdf_of(
        &self,
        mode: BakedMode,
        tables: &Tables,
        adjoint: bool,
        comps: &[Component],
        sampled: Vec3,
        drawn: Option<(usize, Drawn)>,
    ) -> f32 {
        let n = comps.len();
        let wo = near_unit(sampled.as_dvec3());
        // (NaN fails too: near_unit gives 0 for it.)
        if wo.z <= 0.0 {
            return 0.0;
        }
        let delta = if n == 0 { 1.0 } else { self.config.defensive };
        let mut p = delta * wo.z * core::f64::consts::FRAC_1_PI;
        for (k, c) in comps[..n].iter().enumerate() {
            let known = drawn.as_ref().filter(|d| d.0 == k).map(|d| &d.1);
            p += (1.0 - delta) * c.weight * self.component_pdf(mode, tables, adjoint, c, wo, known);
        }
        p as f32
    }

    /// f_r for a role: (given, sampled) are (wi, wo) for [`Role::Importance`] and (wo, wi)
    /// for [`Role::Radiance`].
    #[inline]
    pub(crate) fn eval_unit(&self, role: Role, given: Vec3, sampled: Vec3) -> Vec3 {
        match role {
            Role::Importance => self.brdf.eval(given, sampled),
            Role::Radiance => self.brdf.eval(sampled, given),
        }
    }

    /// The draw behind [`BakedSampler::sample_continuous_as`], at a checked `given`.
    pub(crate) fn sample_unit<R: Rng + ?Sized>(
        &self,
        role: Role,
        given: Vec3,
        uc: f32,
        u: Vec2,
        rng: &mut R,
    ) -> Option<Sample> {
        let (tables, _) = self.tables_for(role);
        let mut comps = Components::new();
        let n = self.components(self.mode, tables, given, &mut comps);
        self.sample_from(self.mode, role, given, &comps[..n], uc, u, rng)
    }

    /// The draw of [`BakedSampler::sample_unit`] from the mixture's components at `given`
    /// (made by [`BakedSampler::components`] for this role and `mode`).
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn sample_from<R: Rng + ?Sized>(
        &self,
        mode: BakedMode,
        role: Role,
        given: Vec3,
        comps: &[Component],
        uc: f32,
        u: Vec2,
        rng: &mut R,
    ) -> Option<Sample> {
        let (tables, adjoint) = self.tables_for(role);
        let n = comps.len();
        let delta = if n == 0 { 1.0 } else { self.config.defensive };
        let uc = f64::from(uc.clamp(0.0, 1.0));
        let mut trials = 1;
        let mut drawn = None;
        let wo = if uc < delta || n == 0 {
            sample_cosine_hemisphere(u)
        } else {
            let mut x = (uc - delta) / (1.0 - delta);
            let mut pick = n - 1;
            for (k, c) in comps[..n].iter().enumerate() {
                if x < c.weight {
                    pick = k;
                    break;
                }
                x -= c.weight;
            }
            let c = &comps[pick];
            let s = &tables.slices[c.slice];
            match mode {
                BakedMode::Rejection => {
                    let leaf = s.tree.select(crate::sampler::descent_uniform(u));
                    // Each trial's point is judged by f where the pdf will look for it: the
                    // point carried to the local frame as the sample would be, and back as
                    // `component_pdf` carries it (the same expressions, so the same bits;
                    // within rounding of the point itself). The accepted trial's f then gives
                    // this component's density without evaluating the model again.
                    let known = core::cell::Cell::new(None);
                    let judge = |w: Vec3| {
                        let wo = c.carry(w.as_dvec3());
                        match c.back(near_unit(wo.as_dvec3())) {
                            Some((back, jacobian)) if back.z > 0.0 && wo.z > 0.0 => {
                                let f = self.table_eval(adjoint, s.wi, back.as_vec3());
                                let y = f64::from(luminance(f));
                                known.set(Some((wo, y * back.z * s.rejection_scale * jacobian)));
                                f
                            }
                            _ => {
                                // Lost after the map (or on the horizon): judged as drawn.
                                known.set(None);
                                self.table_eval(adjoint, s.wi, w)
                            }
                        }
                    };
                    let Some((_, w, _, t)) =
                        rejection_in_leaf(&s.tree, &leaf, judge, rng, &self.violations)
                    else {
                        self.gave_up.fetch_add(1, Ordering::Relaxed);
                        return None;
                    };
                    trials = t;
                    match known.get() {
                        Some((wo, d)) => {
                            drawn = Some((pick, Drawn::Density(d)));
                            wo
                        }
                        None => c.carry(w.as_dvec3()),
                    }
                }
                BakedMode::Warp => {
                    let (p, leaf) = s.warp.warp(u.as_dvec2())?;
                    drawn = Some((pick, Drawn::Warp(leaf)));
                    c.carry(s.map.square_to_direction_f64(p)?)
                }
            }
        };
        if !above_horizon(wo) {
            return None;
        }
        let pdf = self.pdf_of(mode, tables, adjoint, &comps[..n], wo, drawn);
        if !(pdf > 0.0 && pdf.is_finite()) {
            return None;
        }
        let f = self.eval_unit(role, given, wo);
        Sample::continuous(wo, f, pdf).map(|s| Sample { trials, ..s })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The half-vector transport's two maps are each other's inverse, and its density factor
    /// is the ratio of solid angles the map makes: against finite differences (a small
    /// triangle around a tree direction and its image), over tree and query directions across
    /// the hemisphere and a folded (reflected) local frame. The factor inverted, (g·h)/(k·h),
    /// fails it.
    #[test]
    fn the_half_vector_maps_invert_and_their_factor_is_the_jacobian() {
        let dir = |t: f64, p: f64| {
            let (t, p) = (t.to_radians(), p.to_radians());
            DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
        };
        let mut checked = 0;
        for (tree, given) in [
            ((30.0, 0.0), (35.0, 10.0)),
            ((0.0, 0.0), (60.0, 80.0)),
            ((80.0, 45.0), (88.0, 30.0)),
        ] {
            for unfold in [DVec3::ONE, DVec3::new(-1.0, 1.0, 1.0)] {
                let m = HalfMap {
                    tree: dir(tree.0, tree.1),
                    given: dir(given.0, given.1),
                    unfold,
                };
                for (t, p) in [
                    (5.0, 0.0),
                    (25.0, 170.0),
                    (40.0, 20.0),
                    (60.0, 250.0),
                    (75.0, 300.0),
                ] {
                    let w = dir(t, p);
                    let Some(wo) = m.forward(w) else { continue };
                    let (back, factor) = m.back(wo).expect("a carried direction maps back");
                    assert!((back - w).length() < 1e-12, "{back} vs {w}");
                    assert!((wo.length() - 1.0).abs() < 1e-12);
                    // Two tangent steps at w and their images.
                    let e = 1e-6;
                    let t1 = w.any_orthonormal_vector();
                    let t2 = w.cross(t1);
                    let step = |v: DVec3| (w + e * v).normalize();
                    let (w1, w2) = (step(t1), step(t2));
                    let (o1, o2) = (m.forward(w1).unwrap(), m.forward(w2).unwrap());
                    let area_tree = (w1 - w).cross(w2 - w).length();
                    let area_local = (o1 - wo).cross(o2 - wo).length();
                    let numeric = area_tree / area_local;
                    assert!(
                        (factor / numeric - 1.0).abs() < 1e-4,
                        "tree {tree:?} given {given:?} w ({t}, {p}): factor {factor}, numeric {numeric}"
                    );
                    checked += 1;
                }
            }
        }
        assert!(checked >= 25, "{checked}");
    }
}
