//! Robust statistics: the median and the MAD-based sigma.

use std::cmp::Ordering;

/// A float with a total order (`f32::total_cmp`, `f64::total_cmp`).
pub trait TotalOrd: Copy {
    /// The IEEE 754 total order.
    fn total_order(&self, other: &Self) -> Ordering;
}

impl TotalOrd for f64 {
    #[inline]
    fn total_order(&self, other: &Self) -> Ordering {
        self.total_cmp(other)
    }
}

impl TotalOrd for f32 {
    #[inline]
    fn total_order(&self, other: &Self) -> Ordering {
        self.total_cmp(other)
    }
}

/// The median of `v` (for an even count, the upper of the two middle values: the element
/// of rank `n / 2`), or `None` for an empty slice. Reorders `v` (a selection, O(n)).
#[inline]
pub fn median<T: TotalOrd>(v: &mut [T]) -> Option<T> {
    if v.is_empty() {
        return None;
    }
    let mid = v.len() / 2;
    Some(*v.select_nth_unstable_by(mid, T::total_order).1)
}

/// The statistical median of `xs`: for an even count the mean of the two middle values
/// (what a user's `numpy.median` gives; for reported figures), `None` when empty.
pub fn median_mean(xs: &mut [f64]) -> Option<f64> {
    let n = xs.len();
    let upper = median(xs)?;
    if n % 2 == 1 {
        return Some(upper);
    }
    // After the selection, every element before rank n / 2 is <= it: the lower middle is
    // their maximum.
    let lower = xs[..n / 2]
        .iter()
        .copied()
        .fold(f64::NEG_INFINITY, f64::max);
    Some(0.5 * (lower + upper))
}

/// The robust sigma `1.4826 * median |r|` of residuals `res` (0 for none), using `buf` as
/// scratch space. For Gaussian residuals it estimates their standard deviation.
pub fn robust_sigma(res: &[f64], buf: &mut Vec<f64>) -> f64 {
    buf.clear();
    buf.extend(res.iter().map(|r| r.abs()));
    1.4826 * median(buf).unwrap_or(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_of_odd_even_and_empty() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), Some(2.0));
        assert_eq!(median(&mut [4.0f32, 1.0, 3.0, 2.0]), Some(3.0));
        assert_eq!(median::<f64>(&mut []), None);
        assert_eq!(median(&mut [f64::NAN, 1.0, 2.0]), Some(2.0));
        let mut buf = Vec::new();
        assert_eq!(robust_sigma(&[], &mut buf), 0.0);
        assert!((robust_sigma(&[-1.0, 1.0, 2.0], &mut buf) - 1.4826).abs() < 1e-15);
        // The statistical median averages the two middle values of an even count.
        assert_eq!(median_mean(&mut [4.0, 1.0, 3.0, 2.0]), Some(2.5));
        assert_eq!(median_mean(&mut [7.0, 9.0, 1.0, 3.0, 5.0, 2.0]), Some(4.0));
        assert_eq!(median_mean(&mut [3.0, 1.0, 2.0]), Some(2.0));
        assert_eq!(median_mean(&mut []), None);
    }
}
