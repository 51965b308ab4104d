//! Numbers as the command line prints them: a share that is not exactly 0 or 100 % never
//! prints as 0 or 100, a time too short for milliseconds is given in microseconds, and a count
//! takes the singular or the plural of its noun.

/// A percentage with `decimals` decimals, but one that is above 0 and below 100 and rounds to
/// 0 or 100 prints as `< 0.01` or `> 99.99` (with `decimals` 2): a tooth whose every voxel but
/// one is occupied is not "100.00 %" occupied.
pub fn percent(value: f64, decimals: usize) -> String {
    let text = format!("{value:.decimals$}");
    if value > 0.0 && value < 100.0 {
        let step = 10f64.powi(-(decimals as i32));
        let shown = text.parse::<f64>().unwrap_or(value);
        if shown == 0.0 {
            return format!("< {step:.decimals$}");
        }
        if shown == 100.0 {
            return format!("> {:.decimals$}", 100.0 - step);
        }
    }
    text
}

/// A duration given in milliseconds: `0.23 ms`; one that would print as `0.00 ms` but is not 0,
/// in microseconds (`3.35 µs`; `0.40 ns` below that).
pub fn milliseconds(ms: f64) -> String {
    if ms == 0.0 || format!("{ms:.2}") != "0.00" {
        format!("{ms:.2} ms")
    } else if ms * 1e3 >= 0.005 {
        format!("{:.2} µs", ms * 1e3)
    } else {
        format!("{:.2} ns", ms * 1e6)
    }
}

/// `count` and its noun, singular for 1: `1 bit`, `2 bits`, `1 chart`.
pub fn count(count: impl std::fmt::Display, singular: &str, plural: &str) -> String {
    let text = count.to_string();
    let noun = if text == "1" { singular } else { plural };
    format!("{text} {noun}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_share_that_is_not_0_or_100_never_prints_as_either() {
        assert_eq!(percent(99.999, 2), "> 99.99");
        assert_eq!(percent(0.004, 2), "< 0.01");
        assert_eq!(percent(99.96, 1), "> 99.9");
        assert_eq!(percent(0.04, 1), "< 0.1");
        // Exact ends and everything between print as before.
        assert_eq!(percent(100.0, 2), "100.00");
        assert_eq!(percent(0.0, 2), "0.00");
        assert_eq!(percent(99.994, 2), "99.99");
        assert_eq!(percent(48.83, 1), "48.8");
    }

    #[test]
    fn a_time_too_short_for_milliseconds_is_given_in_microseconds() {
        assert_eq!(milliseconds(0.23), "0.23 ms");
        assert_eq!(milliseconds(0.0), "0.00 ms");
        assert_eq!(milliseconds(0.00335), "3.35 µs");
        assert_eq!(milliseconds(0.0000004), "0.40 ns");
        assert_eq!(milliseconds(0.005), "0.01 ms");
    }

    #[test]
    fn a_count_of_one_takes_the_singular() {
        assert_eq!(count(1, "bit", "bits"), "1 bit");
        assert_eq!(count(0u64, "bit", "bits"), "0 bits");
        assert_eq!(count(2usize, "chart", "charts"), "2 charts");
    }
}
