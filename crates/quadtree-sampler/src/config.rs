//! Build options (SPEC §3), with the seed's choices as defaults.

use crate::error::BuildError;
use brdf_core::DiskMap;

/// The evaluations each built node adds to [`BuildConfig::evaluation_budget`].
pub const EVALUATIONS_PER_NODE: u64 = 4096;

/// The per-node integration rule (applied in the node's chart coordinates, adaptively).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum IntegrationRule {
    /// The seed's uniform midpoint grid with `n` × `n` points per application.
    Midpoint {
        /// Points per axis.
        n: u8,
    },
    /// Gauss–Legendre with `n` × `n` points per application.
    GaussLegendre {
        /// Points per axis.
        n: u8,
    },
}

/// How a quadtree is built. `Default` is the seed's method with safe limits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BuildConfig {
    /// Square ↔ hemisphere map. Default: the seed's orthographic `Codificador`.
    pub map: DiskMap,
    /// A node splits while its acceptance P = v1/(box volume) is below this. Default 0.5 (the
    /// seed's rule; it guarantees at most 2 expected trials per sample).
    pub split_threshold: f64,
    /// The node integration rule. Default Gauss–Legendre 6 × 6.
    pub rule: IntegrationRule,
    /// Relative tolerance of each node's adaptive integral (with an absolute floor of 1e-2 of
    /// it times the total volume). Default 1e-6: far below the statistical noise of 10⁸
    /// samples in one leaf. A model may ask for a looser one
    /// ([`brdf_core::Brdf::integration_tolerance`]: a table read by nearest bin); the larger
    /// of the two is used.
    pub integration_tolerance: f64,
    /// Extra levels of adaptive integration below a node. Default 8. Deep nodes take fewer:
    /// no integration cell is finer than 2⁻²² of the square (a few f32 steps of a direction,
    /// below which f_r, evaluated at f32 directions, is a staircase that refining cannot
    /// resolve).
    pub integration_depth: u8,
    /// Maximum node depth (root = 0). Default 20.
    pub max_depth: u8,
    /// Maximum number of nodes. Default 2²⁰.
    pub node_budget: u32,
    /// The f_r evaluations the build may spend (integration and bound search, counted per
    /// rule application) beyond [`EVALUATIONS_PER_NODE`] for every node it has built.
    /// Default 2²⁸ ≈ 2.7 × 10⁸: 4× the most a small registry tree needed in the grazing
    /// sweep (Cook–Torrance m = 0.05 at cos θi = 10⁻⁴: 7 × 10⁷ for 1 221 nodes), about 8 s
    /// of Cook–Torrance on two cores; large trees (Oren–Nayar's target-mode tree of 3 × 10⁵
    /// nodes) live on the per-node allowance. Like the node budget it stops the splitting
    /// between batches of nodes (so the tree stays deterministic), and the build then ends
    /// typed ([`BuildError::Exhausted`]) unless what was built can already be sampled. It
    /// bounds the build's time when each node's integration gets expensive (a lobe too
    /// sharp for the tree's depth), where the node budget alone would allow hours.
    pub evaluation_budget: u64,
    /// Refine further, greedily by wasted volume, until the expected number of rejection
    /// trials per sample is at most this (SPEC §3); at least `bound_safety`, E\[T\]'s floor.
    /// Default `None`: the seed's rule, whose bound E\[T\] ≤ 1/`split_threshold` is always
    /// enforced.
    pub target_trials: Option<f64>,
    /// Bounds are the largest value found (dense grid, peak hints, local search) times this.
    /// Default 1.02.
    pub bound_safety: f64,
    /// Grid points per axis when bounding a node. Default 8 (81 points with the edges).
    pub bound_grid: u8,
    /// The breadth-first pass does not split a node whose wasted volume (box − v1) is below
    /// this fraction of the total volume: without it, leaves on the disk's rim, whose P never
    /// reaches ½, would split until the budget runs out (the seed's endless recursion).
    /// E\[T\] ≤ 1/`split_threshold` is then restored by splitting the most wasteful leaves
    /// first. Default 1e-3.
    pub min_relative_waste: f64,
    /// Evaluate the nodes of a level in parallel (feature `rayon`). The tree is bit-identical
    /// either way. Default true.
    pub parallel: bool,
}

impl Default for BuildConfig {
    fn default() -> Self {
        Self {
            map: DiskMap::Orthographic,
            split_threshold: 0.5,
            rule: IntegrationRule::GaussLegendre { n: 6 },
            integration_tolerance: 1e-6,
            integration_depth: 8,
            max_depth: 20,
            node_budget: 1 << 20,
            evaluation_budget: 1 << 28,
            target_trials: None,
            bound_safety: 1.02,
            bound_grid: 8,
            min_relative_waste: 1e-3,
            parallel: true,
        }
    }
}

impl BuildConfig {
    /// The default with a target mean number of trials (SPEC §3's target mode).
    #[must_use]
    pub fn with_target_trials(target: f64) -> Self {
        Self {
            target_trials: Some(target),
            ..Self::default()
        }
    }

    /// Checks every option's range.
    pub fn validate(&self) -> Result<(), BuildError> {
        let bad = |option, value, expected| {
            Err(BuildError::OutOfRange {
                option,
                value,
                expected,
            })
        };
        if !(self.split_threshold > 0.0 && self.split_threshold <= 1.0) {
            return bad("split_threshold", self.split_threshold, "in (0, 1]");
        }
        if !(self.integration_tolerance > 0.0 && self.integration_tolerance < 1.0) {
            return bad(
                "integration_tolerance",
                self.integration_tolerance,
                "in (0, 1)",
            );
        }
        let n = match self.rule {
            IntegrationRule::Midpoint { n } | IntegrationRule::GaussLegendre { n } => n,
        };
        if !(1..=64).contains(&n) {
            return bad("integration rule size", f64::from(n), "in [1, 64]");
        }
        if self.max_depth > 30 {
            return bad("max_depth", f64::from(self.max_depth), "at most 30");
        }
        if self.node_budget < 1 {
            return bad("node_budget", f64::from(self.node_budget), "at least 1");
        }
        if self.evaluation_budget < 1 {
            return bad(
                "evaluation_budget",
                self.evaluation_budget as f64,
                "at least 1",
            );
        }
        if !(self.bound_safety >= 1.0 && self.bound_safety.is_finite()) {
            return bad("bound_safety", self.bound_safety, "at least 1");
        }
        // Every leaf's box is at least bound_safety × its v1, so E[T] never falls below the
        // safety factor: a smaller target would split until the node budget ran out (20 s
        // and 1M nodes for Lambert) and still miss.
        if let Some(t) = self.target_trials
            && (t.is_nan() || t < self.bound_safety)
        {
            return bad(
                "target_trials",
                t,
                "at least bound_safety (1.02 by default): E[T] cannot fall below the bounds' \
                 safety factor",
            );
        }
        // The seed's rule promises E[T] ≤ 1/split_threshold, and the build enforces it; for
        // the same reason a threshold above 1/bound_safety (0.98 by default) asks for what no
        // tree gives: every node's P stays below it, so every node splits until a budget
        // stops the build.
        if 1.0 / self.split_threshold < self.bound_safety {
            return bad(
                "split_threshold",
                self.split_threshold,
                "at most 1/bound_safety (0.98 by default): a leaf's acceptance P never exceeds \
                 1/bound_safety, so above it every node would split until a budget ran out",
            );
        }
        if !(2..=64).contains(&self.bound_grid) {
            return bad("bound_grid", f64::from(self.bound_grid), "in [2, 64]");
        }
        if !(self.min_relative_waste >= 0.0 && self.min_relative_waste < 1.0) {
            return bad("min_relative_waste", self.min_relative_waste, "in [0, 1)");
        }
        Ok(())
    }
}
