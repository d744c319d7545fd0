//! Small statistics for the tools' reports: percentiles and means of samples.

/// Percentiles of a set of samples (NaNs are ignored).
#[derive(Debug, Clone, Default)]
pub struct Samples {
    sorted: Vec<f64>,
}

impl Samples {
    /// Collects and sorts the values, dropping NaNs.
    pub fn new(values: impl IntoIterator<Item = f64>) -> Self {
        let mut sorted: Vec<f64> = values.into_iter().filter(|v| !v.is_nan()).collect();
        sorted.sort_by(f64::total_cmp);
        Self { sorted }
    }

    /// Number of samples (NaNs excluded).
    pub fn len(&self) -> usize {
        self.sorted.len()
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.sorted.is_empty()
    }

    /// The `p`-th percentile (`p` in 0..=100, nearest rank); NaN when empty.
    pub fn percentile(&self, p: f64) -> f64 {
        if self.sorted.is_empty() {
            return f64::NAN;
        }
        let rank = (p / 100.0 * self.sorted.len() as f64).ceil() as usize;
        self.sorted[rank.clamp(1, self.sorted.len()) - 1]
    }

    /// The median (50th percentile).
    pub fn median(&self) -> f64 {
        self.percentile(50.0)
    }

    /// The largest sample; NaN when empty.
    pub fn max(&self) -> f64 {
        self.sorted.last().copied().unwrap_or(f64::NAN)
    }

    /// The arithmetic mean; NaN when empty.
    pub fn mean(&self) -> f64 {
        self.sorted.iter().sum::<f64>() / self.sorted.len() as f64
    }

    /// The samples, ascending.
    pub fn sorted(&self) -> &[f64] {
        &self.sorted
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_rank_percentiles() {
        let s = Samples::new((1..=100).rev().map(f64::from).chain([f64::NAN]));
        assert_eq!(s.len(), 100);
        assert_eq!(
            [
                s.percentile(0.0),
                s.median(),
                s.percentile(99.0),
                s.percentile(99.9),
                s.max()
            ],
            [1.0, 50.0, 99.0, 100.0, 100.0]
        );
        assert_eq!(s.mean(), 50.5);
        let empty = Samples::new([]);
        assert!(empty.median().is_nan() && empty.mean().is_nan() && empty.max().is_nan());
        assert_eq!(Samples::new([7.0]).percentile(99.0), 7.0);
    }
}
