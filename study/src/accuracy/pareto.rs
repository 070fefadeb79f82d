//! The Pareto front of error against time: the cheapest setting for each error level.

/// Indices of the front, cheapest first: sorted by time (ties: lower error first), a
/// setting is kept when its error is lower than that of every cheaper setting. Entries
/// with a non-finite time or error are never on the front.
pub fn pareto_front(time_error: &[(f64, f64)]) -> Vec<usize> {
    let mut order: Vec<usize> =
        (0..time_error.len()).filter(|&i| time_error[i].0.is_finite() && time_error[i].1.is_finite()).collect();
    order.sort_by(|&a, &b| {
        let (ta, ea) = time_error[a];
        let (tb, eb) = time_error[b];
        ta.total_cmp(&tb).then(ea.total_cmp(&eb))
    });
    let mut best = f64::INFINITY;
    order
        .into_iter()
        .filter(|&i| {
            let keep = time_error[i].1 < best;
            if keep {
                best = time_error[i].1;
            }
            keep
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keeps_the_cheapest_setting_per_error_level() {
        let pts = [
            (4.0, 0.10),     // 0: dominated by 1 (slower and worse)
            (1.0, 0.50),     // 1: cheapest
            (2.0, 0.60),     // 2: slower than 1 and worse
            (3.0, 0.05),     // 3: front
            (2.5, 0.20),     // 4: front
            (5.0, 0.01),     // 5: front
            (5.0, 0.02),     // 6: same time as 5, worse
            (0.5, f64::NAN), // 7: no error measured
        ];
        assert_eq!(pareto_front(&pts), vec![1, 4, 3, 5]);
    }

    #[test]
    fn empty_and_single() {
        assert!(pareto_front(&[]).is_empty());
        assert_eq!(pareto_front(&[(1.0, 1.0)]), vec![0]);
    }
}
