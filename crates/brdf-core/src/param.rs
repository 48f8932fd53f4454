//! Parameter metadata and values, so that the CLI and the viewer can list, parse, validate and
//! edit any model generically (names, defaults and ranges exactly as in MODELS.md).

use crate::error::ParamError;
use alloc::format;
use alloc::string::{String, ToString};
use alloc::vec::Vec;
use glam::Vec3;

/// What kind of value a parameter takes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ParamKind {
    /// One number.
    Scalar,
    /// An RGB triple; written as one value (all channels) or three, `kd=0.9,0.6,0.5`.
    Rgb,
    /// A file path (a measured BRDF's data); its default is empty: no file.
    Path,
    /// One of a fixed set of names (the first is the default unless the spec says otherwise).
    Choice(&'static [&'static str]),
}

/// One parameter of a model: its name, kind, default, range and meaning.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParamSpec {
    /// The name used on the command line (`--param name=value`).
    pub name: &'static str,
    /// Scalar, RGB, path or choice.
    pub kind: ParamKind,
    /// The default value (for a scalar, all three components are equal; for a choice, the
    /// default option's index in `default[0]`; unused for a path).
    pub default: [f32; 3],
    /// Lower end of the range.
    pub min: f32,
    /// Upper end of the range.
    pub max: f32,
    /// True when `min` itself is excluded, as in (0, 1].
    pub min_exclusive: bool,
    /// One line saying what the parameter does, with its unit.
    pub doc: &'static str,
}

impl ParamSpec {
    /// A scalar parameter with the closed range [min, max].
    #[must_use]
    pub const fn scalar(
        name: &'static str,
        default: f32,
        min: f32,
        max: f32,
        doc: &'static str,
    ) -> Self {
        Self {
            name,
            kind: ParamKind::Scalar,
            default: [default; 3],
            min,
            max,
            min_exclusive: false,
            doc,
        }
    }

    /// An RGB parameter with the closed range [min, max] per channel.
    #[must_use]
    pub const fn rgb(
        name: &'static str,
        default: [f32; 3],
        min: f32,
        max: f32,
        doc: &'static str,
    ) -> Self {
        Self {
            name,
            kind: ParamKind::Rgb,
            default,
            min,
            max,
            min_exclusive: false,
            doc,
        }
    }

    /// A file path parameter (default: empty, no file).
    #[must_use]
    pub const fn path(name: &'static str, doc: &'static str) -> Self {
        Self {
            name,
            kind: ParamKind::Path,
            default: [0.0; 3],
            min: 0.0,
            max: 0.0,
            min_exclusive: false,
            doc,
        }
    }

    /// A choice among `options`, defaulting to `options[default]`.
    #[must_use]
    pub const fn choice(
        name: &'static str,
        options: &'static [&'static str],
        default: usize,
        doc: &'static str,
    ) -> Self {
        Self {
            name,
            kind: ParamKind::Choice(options),
            default: [default as f32; 3],
            min: 0.0,
            max: 0.0,
            min_exclusive: false,
            doc,
        }
    }

    /// Whether the value is a number or an RGB triple (the kinds with a range).
    #[must_use]
    pub fn is_numeric(&self) -> bool {
        matches!(self.kind, ParamKind::Scalar | ParamKind::Rgb)
    }

    /// The same parameter with its lower end excluded: (min, max].
    #[must_use]
    pub const fn min_exclusive(mut self) -> Self {
        self.min_exclusive = true;
        self
    }

    /// The range as written in MODELS.md, e.g. `[0, 1]` or `(0, 1]`; for a choice its options
    /// (`nearest|linear`), for a path `a file path`.
    #[must_use]
    pub fn range_text(&self) -> String {
        match self.kind {
            ParamKind::Path => return "a file path".to_string(),
            ParamKind::Choice(options) => return options.join("|"),
            ParamKind::Scalar | ParamKind::Rgb => {}
        }
        format!(
            "{}{}, {}]",
            if self.min_exclusive { "(" } else { "[" },
            self.min,
            self.max
        )
    }

    /// The default as a [`ParamValue`].
    #[must_use]
    pub fn default_value(&self) -> ParamValue {
        match self.kind {
            ParamKind::Scalar => ParamValue::Scalar(self.default[0]),
            ParamKind::Rgb => ParamValue::Rgb(Vec3::from_array(self.default)),
            ParamKind::Path => ParamValue::Path(String::new()),
            ParamKind::Choice(options) => {
                ParamValue::Choice(options[(self.default[0] as usize).min(options.len() - 1)])
            }
        }
    }

    /// Whether `v` lies in the range (NaN never does).
    #[must_use]
    pub fn contains(&self, v: f32) -> bool {
        let lo = if self.min_exclusive {
            v > self.min
        } else {
            v >= self.min
        };
        lo && v <= self.max
    }

    /// Checks one scalar against the range: `Ok(v)` or [`ParamError::OutOfRange`].
    pub fn check_scalar(&self, v: f32) -> Result<f32, ParamError> {
        if self.contains(v) {
            Ok(v)
        } else {
            Err(ParamError::OutOfRange {
                name: self.name,
                value: v,
                range: self.range_text(),
            })
        }
    }

    /// Checks every channel of an RGB value against the range.
    pub fn check_rgb(&self, v: Vec3) -> Result<Vec3, ParamError> {
        for c in v.to_array() {
            self.check_scalar(c)?;
        }
        Ok(v)
    }

    /// Checks a value of either kind against this spec (kind and range).
    pub fn check(&self, v: ParamValue) -> Result<ParamValue, ParamError> {
        match (self.kind, v) {
            (ParamKind::Path, ParamValue::Path(p)) => Ok(ParamValue::Path(p)),
            (ParamKind::Choice(options), ParamValue::Choice(c)) => self.choose(options, c),
            (ParamKind::Path | ParamKind::Choice(_), v) => Err(ParamError::BadValue {
                name: self.name,
                text: v.to_string(),
                expected: match self.kind {
                    ParamKind::Path => "a file path",
                    _ => "one of the listed options",
                },
            }),
            (
                ParamKind::Scalar | ParamKind::Rgb,
                v @ (ParamValue::Path(_) | ParamValue::Choice(_)),
            ) => Err(ParamError::BadValue {
                name: self.name,
                text: v.to_string(),
                expected: "a number",
            }),
            (ParamKind::Scalar, ParamValue::Scalar(x)) => {
                self.check_scalar(x).map(ParamValue::Scalar)
            }
            (ParamKind::Rgb, ParamValue::Rgb(c)) => self.check_rgb(c).map(ParamValue::Rgb),
            (ParamKind::Rgb, ParamValue::Scalar(x)) => {
                self.check_rgb(Vec3::splat(x)).map(ParamValue::Rgb)
            }
            (ParamKind::Scalar, ParamValue::Rgb(c)) => Err(ParamError::BadValue {
                name: self.name,
                text: format!("{},{},{}", c.x, c.y, c.z),
                expected: "one number",
            }),
        }
    }

    /// The option of `options` named `name`, or [`ParamError::BadValue`].
    fn choose(
        &self,
        options: &'static [&'static str],
        name: &str,
    ) -> Result<ParamValue, ParamError> {
        options
            .iter()
            .find(|o| **o == name)
            .map(|o| ParamValue::Choice(o))
            .ok_or_else(|| ParamError::BadValue {
                name: self.name,
                text: name.to_string(),
                expected: "one of the listed options (see `brdf models`)",
            })
    }

    /// Parses the text after `=`: one number, or for RGB one or three comma-separated numbers;
    /// a path as written (not trimmed: a file name may hold spaces); a choice by its name.
    pub fn parse(&self, text: &str) -> Result<ParamValue, ParamError> {
        let bad = |expected| ParamError::BadValue {
            name: self.name,
            text: text.to_string(),
            expected,
        };
        match self.kind {
            ParamKind::Path => return Ok(ParamValue::Path(text.to_string())),
            ParamKind::Choice(options) => return self.choose(options, text.trim()),
            ParamKind::Scalar | ParamKind::Rgb => {}
        }
        let nums: Result<Vec<f32>, _> = text.split(',').map(|s| s.trim().parse::<f32>()).collect();
        let nums = nums.map_err(|_| {
            bad(match self.kind {
                ParamKind::Rgb => "one number or three comma-separated numbers",
                _ => "a number",
            })
        })?;
        let value = match (self.kind, nums.as_slice()) {
            (_, [x]) => ParamValue::Scalar(*x),
            (ParamKind::Rgb, [r, g, b]) => ParamValue::Rgb(Vec3::new(*r, *g, *b)),
            (ParamKind::Rgb, _) => return Err(bad("one number or three comma-separated numbers")),
            (_, _) => return Err(bad("a number")),
        };
        self.check(value)
    }
}

/// A parameter's value.
#[derive(Clone, Debug, PartialEq)]
pub enum ParamValue {
    /// One number.
    Scalar(f32),
    /// An RGB triple.
    Rgb(Vec3),
    /// A file path (empty: none given).
    Path(String),
    /// One option of a [`ParamKind::Choice`].
    Choice(&'static str),
}

impl ParamValue {
    /// The value as RGB (a scalar is splatted; a path or a choice is NaN: not a number).
    #[must_use]
    pub fn rgb(&self) -> Vec3 {
        match self {
            Self::Scalar(x) => Vec3::splat(*x),
            Self::Rgb(c) => *c,
            Self::Path(_) | Self::Choice(_) => Vec3::NAN,
        }
    }

    /// The value as one number (an RGB value gives its first channel; a path or a choice is
    /// NaN).
    #[must_use]
    pub fn scalar(&self) -> f32 {
        match self {
            Self::Scalar(x) => *x,
            Self::Rgb(c) => c.x,
            Self::Path(_) | Self::Choice(_) => f32::NAN,
        }
    }

    /// The text of a path or a choice (`None` for numbers).
    #[must_use]
    pub fn text(&self) -> Option<&str> {
        match self {
            Self::Path(p) => Some(p),
            Self::Choice(c) => Some(c),
            Self::Scalar(_) | Self::Rgb(_) => None,
        }
    }
}

impl core::fmt::Display for ParamValue {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Scalar(x) => write!(f, "{x}"),
            Self::Rgb(c) if c.x == c.y && c.y == c.z => write!(f, "{}", c.x),
            Self::Rgb(c) => write!(f, "{},{},{}", c.x, c.y, c.z),
            Self::Path(p) => f.write_str(p),
            Self::Choice(c) => f.write_str(c),
        }
    }
}

/// A complete, validated set of values for one model's parameters, in the order of its specs.
/// Starts from the defaults; [`ParamSet::set`] and [`ParamSet::assign`] change one value.
#[derive(Clone, Debug, PartialEq)]
pub struct ParamSet {
    model: &'static str,
    specs: &'static [ParamSpec],
    values: Vec<ParamValue>,
}

impl ParamSet {
    /// Every parameter at its default.
    #[must_use]
    pub fn defaults(model: &'static str, specs: &'static [ParamSpec]) -> Self {
        Self {
            model,
            specs,
            values: specs.iter().map(ParamSpec::default_value).collect(),
        }
    }

    /// The model these values are for.
    #[must_use]
    pub fn model(&self) -> &'static str {
        self.model
    }

    /// The specs, in order.
    #[must_use]
    pub fn specs(&self) -> &'static [ParamSpec] {
        self.specs
    }

    /// (spec, value) pairs in order.
    pub fn iter(&self) -> impl Iterator<Item = (&'static ParamSpec, ParamValue)> + '_ {
        self.specs.iter().zip(self.values.iter().cloned())
    }

    fn index(&self, name: &str) -> Result<usize, ParamError> {
        self.specs
            .iter()
            .position(|s| s.name == name)
            .ok_or_else(|| ParamError::UnknownParam {
                model: self.model,
                name: name.to_string(),
                known: self
                    .specs
                    .iter()
                    .map(|s| s.name)
                    .collect::<Vec<_>>()
                    .join(", "),
            })
    }

    /// The value of `name`.
    pub fn get(&self, name: &str) -> Result<ParamValue, ParamError> {
        Ok(self.values[self.index(name)?].clone())
    }

    /// Sets `name` after checking kind and range (RGB parameters accept a scalar).
    pub fn set(&mut self, name: &str, value: ParamValue) -> Result<(), ParamError> {
        let i = self.index(name)?;
        self.values[i] = self.specs[i].check(value)?;
        Ok(())
    }

    /// Applies one `name=value` assignment as written on the command line.
    pub fn assign(&mut self, text: &str) -> Result<(), ParamError> {
        let (name, value) = text.split_once('=').ok_or_else(|| ParamError::Malformed {
            text: text.to_string(),
        })?;
        let i = self.index(name.trim())?;
        self.values[i] = self.specs[i].parse(value)?;
        Ok(())
    }

    /// The scalar value of `name`; for use by model constructors (the name must exist).
    pub fn scalar(&self, name: &str) -> Result<f32, ParamError> {
        self.get(name).map(|v| v.scalar())
    }

    /// The text of a path or choice parameter `name` (empty for a number).
    pub fn text(&self, name: &str) -> Result<&str, ParamError> {
        let i = self.index(name)?;
        Ok(self.values[i].text().unwrap_or(""))
    }

    /// The RGB value of `name`; for use by model constructors (the name must exist).
    pub fn rgb(&self, name: &str) -> Result<Vec3, ParamError> {
        self.get(name).map(|v| v.rgb())
    }
}

impl ParamSet {
    /// A set from values already checked by a model constructor (crate-internal).
    pub(crate) fn from_checked(
        model: &'static str,
        specs: &'static [ParamSpec],
        values: &[ParamValue],
    ) -> Self {
        debug_assert_eq!(specs.len(), values.len());
        Self {
            model,
            specs,
            values: values.to_vec(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SPECS: &[ParamSpec] = &[
        ParamSpec::rgb("kd", [0.5; 3], 0.0, 1.0, "diffuse"),
        ParamSpec::scalar("n", 50.0, 0.0, 1e5, "exponent"),
        ParamSpec::scalar("h", 1.0, 0.0, 1.0, "height").min_exclusive(),
    ];

    #[test]
    fn parse_and_validate() {
        let mut p = ParamSet::defaults("test", SPECS);
        p.assign("kd=0.9,0.6,0.5").unwrap();
        assert_eq!(p.rgb("kd").unwrap(), Vec3::new(0.9, 0.6, 0.5));
        p.assign("kd=0.25").unwrap();
        assert_eq!(p.rgb("kd").unwrap(), Vec3::splat(0.25));
        p.assign(" n = 7 ").unwrap();
        assert_eq!(p.scalar("n").unwrap(), 7.0);

        let e = p.assign("n=1e6").unwrap_err();
        assert!(matches!(e, ParamError::OutOfRange { name: "n", .. }));
        assert!(e.to_string().contains("[0, 100000]"), "{e}");
        assert!(matches!(
            p.assign("n=NaN"),
            Err(ParamError::OutOfRange { .. })
        ));
        assert!(matches!(
            p.assign("n=1,2,3"),
            Err(ParamError::BadValue { .. })
        ));
        assert!(matches!(
            p.assign("kd=1,2"),
            Err(ParamError::BadValue { .. })
        ));
        assert!(matches!(p.assign("kd=x"), Err(ParamError::BadValue { .. })));
        assert!(matches!(p.assign("kd"), Err(ParamError::Malformed { .. })));
        let e = p.assign("q=1").unwrap_err();
        assert!(e.to_string().contains("kd, n, h"), "{e}");
        let e = p.assign("h=0").unwrap_err();
        assert!(e.to_string().contains("(0, 1]"), "{e}");
        p.assign("h=1e-3").unwrap();
        // A failed assignment leaves the previous value.
        assert_eq!(p.scalar("n").unwrap(), 7.0);
    }
}
