//! `brdf models [--json]`.

use crate::CliError;
use brdf_sampling::registry::{self, Energy, ModelInfo};
use brdf_sampling::{ParamKind, ParamSpec};
use serde_json::{Value, json};
use std::io::Write;

/// An f32 as the JSON number with its shortest decimal form (0.8, not 0.800000011920929).
fn num(v: f32) -> Value {
    let shortest: f64 = v
        .to_string()
        .parse()
        .expect("an f32's Display form parses as f64");
    json!(shortest)
}

fn default_json(s: &ParamSpec) -> Value {
    match s.kind {
        ParamKind::Scalar => num(s.default[0]),
        ParamKind::Rgb => Value::Array(s.default.iter().copied().map(num).collect()),
        ParamKind::Path | ParamKind::Choice(_) => json!(s.default_value().to_string()),
    }
}

/// The kind's name in `brdf models --json`: scalar, rgb, path or choice.
fn kind_name(k: ParamKind) -> &'static str {
    match k {
        ParamKind::Scalar => "scalar",
        ParamKind::Rgb => "rgb",
        ParamKind::Path => "path",
        ParamKind::Choice(_) => "choice",
    }
}

fn model_json(m: &ModelInfo) -> Value {
    let (energy, energy_note) = match m.energy {
        Energy::Conserving => ("conserving", ""),
        Energy::ConservingIf(c) => ("conditional", c),
        Energy::NotConserving(c) => ("not-conserving", c),
    };
    json!({
        "name": m.name,
        "summary": m.summary,
        "reciprocal": m.reciprocal,
        "energy": energy,
        "energy_note": energy_note,
        "analytic_sampler": m.analytic_sampler,
        "delta": m.delta,
        "measured": m.measured,
        "params": m.params.iter().map(|s| {
            let mut p = json!({
                "name": s.name,
                "kind": kind_name(s.kind),
                "default": default_json(s),
                "min": if s.is_numeric() { num(s.min) } else { Value::Null },
                "max": if s.is_numeric() { num(s.max) } else { Value::Null },
                "min_exclusive": s.min_exclusive,
                "range": s.range_text(),
                "doc": s.doc,
            });
            if let ParamKind::Choice(options) = s.kind {
                p["options"] = json!(options);
            }
            p
        }).collect::<Vec<_>>(),
    })
}

pub(crate) fn run(json: bool, mut out: impl Write) -> Result<(), CliError> {
    if json {
        let all: Vec<Value> = registry::models().iter().map(model_json).collect();
        serde_json::to_writer_pretty(&mut out, &all).map_err(std::io::Error::from)?;
        writeln!(out)?;
        return Ok(());
    }
    for m in registry::models() {
        writeln!(out, "{}  {}", m.name, m.summary)?;
        for s in m.params {
            let mut default = s.default_value().to_string();
            if default.is_empty() {
                default = "(required)".into();
            }
            let kind = match s.kind {
                ParamKind::Scalar => "",
                ParamKind::Rgb => " (rgb)",
                ParamKind::Path => " (path)",
                ParamKind::Choice(_) => " (choice)",
            };
            writeln!(
                out,
                "    {:<13} default {:<18} range {:<15} {}{kind}",
                s.name,
                default,
                s.range_text(),
                s.doc
            )?;
        }
    }
    Ok(())
}
