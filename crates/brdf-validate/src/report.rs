//! What one test found: the histogram, the statistics, and the typed reasons behind its
//! verdict.

use crate::histogram::Histogram;
use crate::stats::{ChiSquare, Spread};
use std::fmt;

/// What a verdict judges a sampler against.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Against {
    /// SPEC §5: the samples must follow f·cos **and** the sampler's own pdf.
    FCos,
    /// Only the sampler's own pdf: for samplers not meant to follow f·cos (an analytic lobe
    /// sampler, the warp, a baked sampler off its grid).
    OwnPdf,
}

impl Against {
    fn label(self) -> &'static str {
        match self {
            Self::FCos => "f·cos",
            Self::OwnPdf => "its own pdf",
        }
    }
}

/// Why a test rejected, or why it could not judge. Each reason says whether it concerns the
/// sampler judged against its own pdf alone ([`Reason::concerns_own_pdf`]) and whether it
/// rejects or leaves the test inconclusive ([`Reason::is_inconclusive`]).
#[derive(Clone, Debug, PartialEq)]
pub enum Reason {
    /// The expected cell masses are not a distribution: their total is not positive and
    /// finite, or a cell is negative or NaN. All 0 (f_r ≡ 0 at wi) leaves the test against
    /// f·cos unjudged; otherwise it rejects, under either verdict.
    MassesNotADistribution {
        /// Σ I_i.
        total: f64,
    },
    /// The sampler's pdf integrates to more than 1 over the hemisphere (by more than 10⁻³).
    PdfAboveOne {
        /// ∫ pdf dω.
        integral: f64,
    },
    /// A χ² test rejected at the per-test significance.
    ChiSquare {
        /// What the counts were compared with.
        against: Against,
        /// The statistic.
        statistic: f64,
        /// Its degrees of freedom.
        dof: usize,
        /// Its p-value (NaN rejects).
        p_value: f64,
        /// The per-test significance.
        alpha: f64,
    },
    /// Too few pooled bins for a χ² (inconclusive, not a rejection).
    TooFewDegreesOfFreedom {
        /// Which χ² could not run.
        against: Against,
    },
    /// Every sample was lost: the sampler drew nothing.
    AllLost {
        /// Samples asked for.
        samples: u64,
    },
    /// Some samples carried no direction, though f·cos puts every sample somewhere (a
    /// sampler judged on its own pdf may lose them: its pdf then integrates below 1).
    Lost {
        /// Samples lost.
        count: u64,
    },
    /// Samples outside the domain: non-finite, at or below the horizon, or delta.
    Outside {
        /// How many.
        count: u64,
    },
    /// Samples in cells where f·cos integrates to 0.
    InEmptyCells {
        /// How many.
        count: u64,
    },
    /// Samples whose pdf disagreed with `pdf(wo)`, or whose weight with f·cos θ/pdf.
    Inconsistent {
        /// How many of the checked samples.
        count: u64,
    },
}

impl Reason {
    /// True when the reason concerns the sampler judged against its own pdf alone (it counts
    /// under [`Against::OwnPdf`] as well as under [`Against::FCos`]).
    #[must_use]
    pub fn concerns_own_pdf(&self) -> bool {
        match self {
            // Masses that are all 0 (f_r ≡ 0 at wi) say nothing of the sampler's own pdf;
            // broken ones (NaN, negative) break the tolerance its cells are integrated to.
            Self::MassesNotADistribution { total } => *total != 0.0,
            Self::PdfAboveOne { .. }
            | Self::AllLost { .. }
            | Self::Outside { .. }
            | Self::Inconsistent { .. } => true,
            Self::ChiSquare { against, .. } | Self::TooFewDegreesOfFreedom { against } => {
                *against == Against::OwnPdf
            }
            Self::Lost { .. } | Self::InEmptyCells { .. } => false,
        }
    }

    /// True when the reason leaves the test unjudged rather than rejected.
    #[must_use]
    pub fn is_inconclusive(&self) -> bool {
        matches!(
            self,
            Self::TooFewDegreesOfFreedom { .. } | Self::MassesNotADistribution { total: 0.0 }
        )
    }

    /// True when the reason counts for a verdict `against`.
    #[must_use]
    pub fn counts_for(&self, against: Against) -> bool {
        against == Against::FCos || self.concerns_own_pdf()
    }
}

impl fmt::Display for Reason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::MassesNotADistribution { total: 0.0 } => write!(
                f,
                "f_r is 0 everywhere above the horizon at this wi: nothing to compare with f·cos"
            ),
            Self::MassesNotADistribution { total } => write!(
                f,
                "the expected masses are not a distribution (total {total}, a negative or NaN cell)"
            ),
            Self::PdfAboveOne { integral } => {
                write!(f, "the sampler's pdf integrates to {integral:.5} > 1")
            }
            Self::ChiSquare {
                against,
                statistic,
                dof,
                p_value,
                alpha,
            } => write!(
                f,
                "χ² against {} = {statistic:.1} with {dof} dof: p = {p_value:.3e} < α = {alpha:.3e}",
                against.label()
            ),
            Self::TooFewDegreesOfFreedom { against } => write!(
                f,
                "too few degrees of freedom for the χ² against {}: use more samples or cells",
                against.label()
            ),
            Self::AllLost { samples } => write!(
                f,
                "every one of the {samples} samples was lost: the sampler drew nothing"
            ),
            Self::Lost { count } => write!(
                f,
                "{count} samples carried no direction, though f·cos puts every sample somewhere"
            ),
            Self::Outside { count } => write!(
                f,
                "{count} samples outside the domain (non-finite, at or below the horizon, or delta)"
            ),
            Self::InEmptyCells { count } => {
                write!(f, "{count} samples in cells where f·cos integrates to 0")
            }
            Self::Inconsistent { count } => write!(
                f,
                "{count} samples whose pdf or weight disagrees with pdf(wo) or f·cos/pdf"
            ),
        }
    }
}

/// A test's outcome. A rejection outranks an inconclusive test: a sampler that put samples
/// outside the domain is wrong however few samples were drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Verdict {
    /// Every test ran and none rejected.
    Passed,
    /// A test rejected (see [`Report::rejections`]).
    Rejected,
    /// Nothing rejected, but a test could not be run (see [`Report::unjudged`]).
    Inconclusive,
}

impl Verdict {
    /// The outcome of several tests: rejected when any rejected, else inconclusive when any
    /// could not be judged, else passed.
    pub fn overall(verdicts: impl IntoIterator<Item = Verdict>) -> Self {
        let mut out = Self::Passed;
        for v in verdicts {
            match v {
                Self::Rejected => return Self::Rejected,
                Self::Inconclusive => out = Self::Inconclusive,
                Self::Passed => {}
            }
        }
        out
    }
}

/// Everything one test found.
#[derive(Clone, Debug)]
pub struct Report {
    /// The sampler's name.
    pub sampler: String,
    /// Samples drawn.
    pub samples: u64,
    /// Samples per cell against f·cos and the sampler's own pdf (both expectations for all
    /// `samples`).
    pub histogram: Histogram,
    /// Samples the sampler gave no direction for.
    pub lost: u64,
    /// Samples outside the domain (non-finite or at/below the horizon) or flagged delta.
    pub outside: u64,
    /// Samples whose pdf or weight disagreed with `pdf(wo)` or f·cos/pdf.
    pub inconsistent: u64,
    /// Samples in cells where f·cos integrates to 0.
    pub in_empty_cells: u64,
    /// χ² against f·cos (`None`: too few degrees of freedom).
    pub chi2: Option<ChiSquare>,
    /// χ² against the sampler's own pdf, with a bin for lost samples.
    pub chi2_own: Option<ChiSquare>,
    /// The seed's a_i spread (`None` when no cell expects enough samples).
    pub spread: Option<Spread>,
    /// The per-test significance the p-values were judged at.
    pub alpha: f64,
    /// Every reason found, rejections and inconclusive ones, in the order they were checked.
    pub reasons: Vec<Reason>,
}

impl Report {
    /// The reasons that reject under a verdict `against`.
    #[must_use]
    pub fn rejections(&self, against: Against) -> Vec<&Reason> {
        self.reasons
            .iter()
            .filter(|r| !r.is_inconclusive() && r.counts_for(against))
            .collect()
    }

    /// The reasons a verdict `against` could not be judged for.
    #[must_use]
    pub fn unjudged(&self, against: Against) -> Vec<&Reason> {
        self.reasons
            .iter()
            .filter(|r| r.is_inconclusive() && r.counts_for(against))
            .collect()
    }

    /// The outcome against f·cos or the sampler's own pdf.
    #[must_use]
    pub fn verdict_against(&self, against: Against) -> Verdict {
        if !self.rejections(against).is_empty() {
            Verdict::Rejected
        } else if !self.unjudged(against).is_empty() {
            Verdict::Inconclusive
        } else {
            Verdict::Passed
        }
    }

    /// The outcome against f·cos and the sampler's own pdf (SPEC §5).
    #[must_use]
    pub fn verdict(&self) -> Verdict {
        self.verdict_against(Against::FCos)
    }

    /// The outcome against the sampler's own pdf alone.
    #[must_use]
    pub fn verdict_own(&self) -> Verdict {
        self.verdict_against(Against::OwnPdf)
    }

    /// True when every test ran and nothing rejected.
    #[must_use]
    pub fn passed(&self) -> bool {
        self.verdict() == Verdict::Passed
    }

    /// True when the sampler is right about its own pdf, whether or not that pdf follows
    /// f·cos.
    #[must_use]
    pub fn passed_own(&self) -> bool {
        self.verdict_own() == Verdict::Passed
    }
}

impl fmt::Display for Report {
    /// One line of statistics, then one line per reason.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let p = |c: &Option<ChiSquare>| {
            c.as_ref()
                .map_or_else(|| "–".to_string(), |c| format!("{:.3e}", c.p_value))
        };
        write!(
            f,
            "{}: {} samples, p = {} against f·cos, {} against its own pdf, {:?} ({:?} on its own pdf)",
            self.sampler,
            self.samples,
            p(&self.chi2),
            p(&self.chi2_own),
            self.verdict(),
            self.verdict_own()
        )?;
        for r in &self.reasons {
            write!(f, "\n  {r}")?;
        }
        Ok(())
    }
}
