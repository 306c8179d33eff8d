//! Order statistics shared by the layers above (the bottom layer: it
//! imports nothing from the crate).
//!
//! One median for the SLAM core: the element at index `len / 2` once
//! sorted (for an even count, the larger of the two middle ones), as
//! ORB-SLAM3's `KeyFrame::ComputeSceneMedianDepth` takes it
//! (`vDepths[(vDepths.size()-1)/q]` with q = 2 is the lower one there; the
//! difference is one element, and every caller here only needs a robust
//! central value). The evaluation's statistics (`eval::stats`) follow evo
//! instead (the mean of the two middle values) and keep their own.

/// A float type with IEEE 754's total order (`total_cmp`).
pub trait TotalOrder: Copy {
    /// [`f64::total_cmp`] or [`f32::total_cmp`].
    fn total_order(&self, other: &Self) -> std::cmp::Ordering;
}

impl TotalOrder for f64 {
    fn total_order(&self, other: &Self) -> std::cmp::Ordering {
        self.total_cmp(other)
    }
}

impl TotalOrder for f32 {
    fn total_order(&self, other: &Self) -> std::cmp::Ordering {
        self.total_cmp(other)
    }
}

/// The upper median of `values` (index `len / 2` in sorted order), in
/// linear time; `None` when empty. Reorders `values`.
pub fn upper_median<T: TotalOrder>(values: &mut [T]) -> Option<T> {
    if values.is_empty() {
        return None;
    }
    let mid = values.len() / 2;
    let (_, median, _) = values.select_nth_unstable_by(mid, T::total_order);
    Some(*median)
}

#[cfg(test)]
mod tests {
    use super::upper_median;

    #[test]
    fn the_upper_median_is_the_middle_element_of_the_sorted_values() {
        assert_eq!(upper_median::<f64>(&mut []), None);
        assert_eq!(upper_median(&mut [3.0_f64]), Some(3.0));
        assert_eq!(upper_median(&mut [4.0_f64, 1.0]), Some(4.0));
        assert_eq!(upper_median(&mut [5.0_f32, -1.0, 2.0]), Some(2.0));
        assert_eq!(upper_median(&mut [9.0_f64, 2.0, 7.0, 1.0]), Some(7.0));
        // Against sorting, on values with repeats and a negative zero.
        let values = [0.5, -0.0, 0.0, 3.25, 3.25, -7.0, 1e9, 2.0];
        for n in 1..=values.len() {
            let mut sorted = values[..n].to_vec();
            sorted.sort_by(f64::total_cmp);
            let mut shuffled: Vec<f64> = values[..n].iter().rev().copied().collect();
            assert_eq!(upper_median(&mut shuffled), Some(sorted[n / 2]), "n = {n}");
        }
    }
}
