//! The model registry: every model by its MODELS.md name, with its parameter metadata, so that
//! the CLI and the viewer can list, build and edit any model generically.
//!
//! ```
//! use brdf_core::registry;
//! let phong = registry::create("phong", ["n=200", "kd=0.2"]).unwrap();
//! assert_eq!(phong.params().scalar("n").unwrap(), 200.0);
//! assert!(registry::create("phong", ["n=-1"]).is_err());
//! ```

use crate::brdf::Brdf;
use crate::error::{Constraint, ParamError};
use crate::models::{
    BlinnPhong, CookTorrance, Htsg, Lambert, LewisPhong, Merl, Mirror, OrenNayar, Phong,
    PoulinFournier, Schlick, Strauss, Ward,
};
use crate::param::{ParamSet, ParamSpec};
use alloc::boxed::Box;
use alloc::string::ToString;

/// Whether a model conserves energy (directional albedo ≤ 1 at every incidence).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Energy {
    /// For every valid parameter set.
    Conserving,
    /// Only under the stated condition on the parameters.
    ConservingIf(&'static str),
    /// Not in general (the reason in words).
    NotConserving(&'static str),
}

/// One registered model: its name, a one-line description, its parameters and properties.
#[derive(Clone, Copy, Debug)]
pub struct ModelInfo {
    /// The name used on the command line (MODELS.md).
    pub name: &'static str,
    /// One line: the model and its source.
    pub summary: &'static str,
    /// The parameters, in order, with defaults and ranges.
    pub params: &'static [ParamSpec],
    /// Whether f_r(wi, wo) = f_r(wo, wi).
    pub reciprocal: bool,
    /// Energy conservation.
    pub energy: Energy,
    /// Whether the model has its own importance sampler (else cosine sampling is its baseline).
    pub analytic_sampler: bool,
    /// Whether the model is a pure Dirac delta (no continuous part; no quadtree).
    pub delta: bool,
    /// Whether the model is measured data: its defaults build nothing (a `file=PATH` is
    /// required), so suites that build every model from its defaults give it a file of
    /// their own (`brdf tabulate` writes one from any model).
    pub measured: bool,
    build: fn(&ParamSet) -> Result<Box<dyn Brdf>, ParamError>,
}

impl ModelInfo {
    /// Every parameter at its default.
    #[must_use]
    pub fn defaults(&self) -> ParamSet {
        ParamSet::defaults(self.name, self.params)
    }

    /// The defaults with `name=value` assignments applied in order.
    pub fn parse_params<'a>(
        &self,
        assignments: impl IntoIterator<Item = &'a str>,
    ) -> Result<ParamSet, ParamError> {
        let mut p = self.defaults();
        for a in assignments {
            p.assign(a)?;
        }
        Ok(p)
    }

    /// Builds the model (errors for cross-parameter constraints such as kd + ks ≤ 1, or a
    /// parameter set of another model).
    pub fn build(&self, params: &ParamSet) -> Result<Box<dyn Brdf>, ParamError> {
        if params.model() != self.name {
            return Err(ParamError::Constraint {
                model: self.name,
                constraint: Constraint::OtherModel {
                    params_of: params.model(),
                },
            });
        }
        (self.build)(params)
    }
}

fn boxed<B: Brdf + 'static>(b: Result<B, ParamError>) -> Result<Box<dyn Brdf>, ParamError> {
    b.map(|b| Box::new(b) as Box<dyn Brdf>)
}

/// Why HTSG is not listed as energy-conserving (the tests measure it below 1 with a = 0).
const ENERGY_HTSG: &str = "nothing in the model bounds specular + directional-diffuse + a/pi; with a = 0 it measures below 1 on the tested sets";

static MODELS: &[ModelInfo] = &[
    ModelInfo {
        name: "lambert",
        summary: "perfect diffuse reflector, f = albedo/pi",
        params: Lambert::PARAMS,
        reciprocal: true,
        energy: Energy::Conserving,
        analytic_sampler: true,
        delta: false,
        measured: false,
        build: |p| boxed(Lambert::from_params(p)),
    },
    ModelInfo {
        name: "mirror",
        summary: "perfect specular reflector (a Dirac delta toward the mirror direction)",
        params: Mirror::PARAMS,
        reciprocal: true,
        energy: Energy::Conserving,
        analytic_sampler: true,
        delta: true,
        measured: false,
        build: |p| boxed(Mirror::from_params(p)),
    },
    ModelInfo {
        name: "phong",
        summary: "Phong (1975), reciprocal unnormalised form kd/pi + ks cos^n(alpha)",
        params: Phong::PARAMS,
        reciprocal: true,
        energy: Energy::NotConserving("the lobe's albedo at normal incidence is ks*2pi/(n+2)"),
        analytic_sampler: true,
        delta: false,
        measured: false,
        build: |p| boxed(Phong::from_params(p)),
    },
    ModelInfo {
        name: "blinn-phong",
        summary: "Blinn (1977), half-vector lobe with exact normalisation",
        params: BlinnPhong::PARAMS,
        reciprocal: true,
        energy: Energy::ConservingIf("kd + ks <= 1"),
        analytic_sampler: true,
        delta: false,
        measured: false,
        build: |p| boxed(BlinnPhong::from_params(p)),
    },
    ModelInfo {
        name: "lewis-phong",
        summary: "Lewis (1994), normalised Phong kd/pi + ks (n+2)/(2pi) cos^n(alpha)",
        params: LewisPhong::PARAMS,
        reciprocal: true,
        energy: Energy::Conserving,
        analytic_sampler: true,
        delta: false,
        measured: false,
        build: |p| boxed(LewisPhong::from_params(p)),
    },
    ModelInfo {
        name: "cook-torrance",
        summary: "Cook & Torrance (1982), normalised Beckmann microfacet model with V-cavity G and dielectric Fresnel",
        params: CookTorrance::PARAMS,
        reciprocal: true,
        energy: Energy::ConservingIf(
            "kd = 0 (the diffuse term is added on top of the specular part, which conserves energy)",
        ),
        analytic_sampler: true,
        delta: false,
        measured: false,
        build: |p| boxed(CookTorrance::from_params(p)),
    },
    ModelInfo {
        name: "htsg",
        summary: "He, Torrance, Sillion & Greenberg (1991), physical optics: directional-diffuse series plus a specular delta",
        params: Htsg::PARAMS,
        reciprocal: true,
        energy: Energy::NotConserving(ENERGY_HTSG),
        analytic_sampler: false,
        delta: false,
        measured: false,
        build: |p| boxed(Htsg::from_params(p)),
    },
    ModelInfo {
        name: "poulin-fournier",
        summary: "Poulin & Fournier (1990), parallel raised cylinders with a local Lewis-Phong BRDF",
        params: PoulinFournier::PARAMS,
        reciprocal: true,
        energy: Energy::Conserving,
        analytic_sampler: false,
        delta: false,
        measured: false,
        build: |p| boxed(PoulinFournier::from_params(p)),
    },
    ModelInfo {
        name: "oren-nayar",
        summary: "Oren & Nayar (1994), rough diffuse surfaces, full model with inter-reflection",
        params: OrenNayar::PARAMS,
        reciprocal: true,
        energy: Energy::NotConserving("slightly above 1 at grazing incidence for albedo 1"),
        analytic_sampler: true,
        delta: false,
        measured: false,
        build: |p| boxed(OrenNayar::from_params(p)),
    },
    ModelInfo {
        name: "ward",
        summary: "Ward (1992), anisotropic elliptical Gaussian, original normalisation",
        params: Ward::PARAMS,
        reciprocal: true,
        energy: Energy::NotConserving("the albedo grows as 1/sqrt(cos theta_i) near grazing"),
        analytic_sampler: true,
        delta: false,
        measured: false,
        build: |p| boxed(Ward::from_params(p)),
    },
    ModelInfo {
        name: "schlick",
        summary: "Schlick (1994), single slab, single scattering, anisotropic",
        params: Schlick::PARAMS,
        reciprocal: true,
        energy: Energy::NotConserving("above 1 near grazing for small roughness"),
        analytic_sampler: true,
        delta: false,
        measured: false,
        build: |p| boxed(Schlick::from_params(p)),
    },
    ModelInfo {
        name: "strauss",
        summary: "Strauss (1990), artist-oriented smoothness/metalness model in radiometric BRDF form",
        params: Strauss::PARAMS,
        reciprocal: false,
        energy: Energy::NotConserving(
            "the specular term's 1/cos(theta_i) grows without bound at grazing incidence",
        ),
        analytic_sampler: true,
        delta: false,
        measured: false,
        build: |p| boxed(Strauss::from_params(p)),
    },
    ModelInfo {
        name: "merl",
        summary: "measured isotropic BRDF in the MERL database's binary format (Matusik et al. 2003), looked up in half/difference angles",
        params: Merl::PARAMS,
        reciprocal: true,
        energy: Energy::NotConserving("measured data: the albedo is whatever the file holds"),
        analytic_sampler: false,
        delta: false,
        measured: true,
        build: |p| boxed(Merl::from_params(p)),
    },
];

/// Every registered model, in MODELS.md order (the measured `merl` last).
#[must_use]
pub fn models() -> &'static [ModelInfo] {
    MODELS
}

/// The model called `name`, or [`ParamError::UnknownModel`].
pub fn find(name: &str) -> Result<&'static ModelInfo, ParamError> {
    MODELS
        .iter()
        .find(|m| m.name == name)
        .ok_or_else(|| ParamError::UnknownModel {
            name: name.to_string(),
        })
}

/// Builds model `name` from `name=value` assignments (defaults for the rest).
pub fn create<'a>(
    name: &str,
    assignments: impl IntoIterator<Item = &'a str>,
) -> Result<Box<dyn Brdf>, ParamError> {
    let info = find(name)?;
    info.build(&info.parse_params(assignments)?)
}
