//! How the viewer starts: the command line's model, parameters and incident direction,
//! checked before the app exists ([`Launch::resolve`]).

use crate::panels::MAX_THETA_DEG;
use brdf_core::ParamSet;
use brdf_core::geometry::spherical_angles;
use brdf_core::registry::{self, ModelInfo};
use glam::Vec3;

/// How the viewer starts: the model, its parameters and the incident direction.
#[derive(Clone, Debug)]
pub struct Launch {
    /// Registry name of the model.
    pub model: String,
    /// `name=value` parameter assignments, as the `brdf` CLI takes them.
    pub params: Vec<String>,
    /// Incident direction (local frame); `None`: θ = 45°, φ = 30°.
    pub wi: Option<Vec3>,
    /// Samples to draw.
    pub samples: u64,
}

impl Default for Launch {
    fn default() -> Self {
        Self {
            model: "ward".into(),
            params: Vec::new(),
            wi: None,
            samples: 100_000,
        }
    }
}

/// A checked [`Launch`]: everything [`crate::ViewerApp::new`] needs, already validated.
#[derive(Clone, Debug)]
pub struct Resolved {
    pub(crate) model: &'static ModelInfo,
    pub(crate) params: ParamSet,
    pub(crate) theta_deg: f32,
    pub(crate) phi_deg: f32,
    pub(crate) samples: u64,
}

impl Launch {
    /// Checks the model name, the parameters and the incident direction; the error says
    /// which is wrong and why.
    pub fn resolve(&self) -> Result<Resolved, String> {
        let model = registry::find(&self.model).map_err(|e| e.to_string())?;
        let params = model
            .parse_params(self.params.iter().map(String::as_str))
            .map_err(|e| e.to_string())?;
        model.build(&params).map_err(|e| e.to_string())?;
        let (theta_deg, phi_deg) = match self.wi {
            Some(wi) => {
                let wi = brdf_core::geometry::unit_direction_above(wi)
                    .map_err(|e| format!("--wi: {e}"))?;
                let (t, p) = spherical_angles(wi);
                let t = t.to_degrees();
                // Used as given or refused, never moved: the sliders stop at 89°.
                // (A thousandth of a degree of slack for the f32 round trip of 89° itself.)
                if t > MAX_THETA_DEG + 1e-3 {
                    return Err(format!(
                        "--wi: θ = {t:.4}° is beyond the viewer's {MAX_THETA_DEG}° limit (`brdf sample` takes any wi above the horizon)"
                    ));
                }
                (t.min(MAX_THETA_DEG), p.to_degrees())
            }
            None => (45.0, 30.0),
        };
        if !(1..=100_000_000).contains(&self.samples) {
            return Err(format!(
                "--samples {}: must be in 1..=100000000",
                self.samples
            ));
        }
        Ok(Resolved {
            model,
            params,
            theta_deg,
            phi_deg: if phi_deg > 180.0 {
                phi_deg - 360.0
            } else {
                phi_deg
            },
            samples: self.samples,
        })
    }
}
