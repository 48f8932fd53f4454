//! One histogram of a test: the samples counted per cell beside what f·cos (and the sampler's
//! own pdf) expects there. The CLI's images, the viewer's views and both EXR writers read it.

use crate::cells::CellGrid;

/// Samples per cell against the expectation, for one grid (row-major, as
/// [`CellGrid::dims`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Histogram {
    /// The cells.
    pub grid: CellGrid,
    /// Samples counted per cell.
    pub observed: Vec<u64>,
    /// Expected samples per cell under f·cos: m · I_i / Σ I for m counted samples.
    pub expected: Vec<f64>,
    /// Expected samples per cell under the sampler's own pdf (m · ∫ pdf dω over the cell),
    /// when the test integrated it.
    pub expected_own: Option<Vec<f64>>,
    /// ∫ Y(f_r) dA per cell, per unit projected area (the seed's I_i).
    pub mass: Vec<f64>,
}

impl Histogram {
    /// A histogram of `observed` counts against cell integrals `mass` (same length as the
    /// grid), with the expectation m · I_i / Σ I for m = the counts' sum: what a live view
    /// of samples as they arrive compares with (no own-pdf expectation). Masses whose total
    /// is not positive and finite expect nothing anywhere (0, never NaN).
    #[must_use]
    pub fn of_counts(grid: CellGrid, observed: Vec<u64>, mass: Vec<f64>) -> Self {
        let m = observed.iter().sum::<u64>() as f64;
        let total: f64 = mass.iter().sum();
        let expected = if total > 0.0 && total.is_finite() {
            mass.iter().map(|x| m * x / total).collect()
        } else {
            vec![0.0; mass.len()]
        };
        Self {
            grid,
            observed,
            expected,
            expected_own: None,
            mass,
        }
    }

    /// The standardised residual of every cell, (n − e)/√e; a cell that expects nothing reads
    /// 0 when it got nothing and +∞ otherwise (a sample where f·cos has no mass).
    #[must_use]
    pub fn residuals(&self) -> Vec<f64> {
        self.observed
            .iter()
            .zip(&self.expected)
            .map(|(&o, &e)| {
                let o = o as f64;
                if e > 0.0 {
                    (o - e) / e.sqrt()
                } else if o > 0.0 {
                    f64::INFINITY
                } else {
                    0.0
                }
            })
            .collect()
    }

    /// The largest of the observed and expected counts (at least 1): one linear scale for
    /// pictures of both.
    #[must_use]
    pub fn count_scale(&self) -> f64 {
        self.observed
            .iter()
            .map(|&o| o as f64)
            .chain(self.expected.iter().copied())
            .fold(0.0f64, f64::max)
            .max(1.0)
    }

    /// Writes the per-cell arrays as one EXR layer named `layer` of `columns × rows` f32
    /// pixels in [`CellGrid::image_order`], with the channels `expected`, `expected_own`
    /// (when present), `mass`, `observed` and `residual`. Complete or absent: encoded in
    /// memory, then renamed into place.
    #[cfg(feature = "exr")]
    pub fn write_exr(&self, path: &std::path::Path, layer: &str) -> exr::error::UnitResult {
        use exr::prelude::*;
        let (rows, cols) = self.grid.dims();
        let order = self.grid.image_order();
        let channel = |name: &str, values: &dyn Fn(usize) -> f64| {
            AnyChannel::new(
                name,
                FlatSamples::F32(order.iter().map(|&i| values(i) as f32).collect()),
            )
        };
        let residual = self.residuals();
        let mut channels = vec![channel("expected", &|i| self.expected[i])];
        if let Some(own) = &self.expected_own {
            channels.push(channel("expected_own", &|i| own[i]));
        }
        channels.push(channel("mass", &|i| self.mass[i]));
        channels.push(channel("observed", &|i| self.observed[i] as f64));
        channels.push(channel("residual", &|i| residual[i]));
        let layer = Layer::new(
            (cols, rows),
            LayerAttributes::named(layer),
            Encoding::FAST_LOSSLESS,
            AnyChannels::sort(channels.into()),
        );
        let mut bytes = std::io::Cursor::new(Vec::new());
        Image::from_layer(layer).write().to_buffered(&mut bytes)?;
        quadtree_sampler::write_atomically(path, bytes.get_ref()).map_err(exr::error::Error::Io)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn residuals_and_the_live_expectation() {
        let grid = CellGrid::Square { res: 2 };
        let h = Histogram::of_counts(grid, vec![30, 10, 0, 1], vec![3.0, 1.0, 0.0, 0.0]);
        assert_eq!(h.expected, vec![30.75, 10.25, 0.0, 0.0]);
        let r = h.residuals();
        assert!((r[0] - (30.0 - 30.75) / 30.75f64.sqrt()).abs() < 1e-15);
        assert_eq!((r[2], r[3]), (0.0, f64::INFINITY));
        assert_eq!(h.count_scale(), 30.75);
        let empty = Histogram::of_counts(grid, vec![1, 0, 0, 0], vec![0.0; 4]);
        assert_eq!(empty.expected, vec![0.0; 4]);
        assert_eq!(empty.residuals()[0], f64::INFINITY);
    }
}
