//! Primary/standby forecasters: which instance serves a robot.
//!
//! Every forecaster instance has a rank (0 = primary, 1 = first standby, …) and holds the
//! liveliness token `echo/<robot>/alive/forecaster-r<rank>` for each robot it can serve. An
//! instance is *active* for a robot — publishes its forecasts and holds the plain
//! `forecaster` token — exactly when no instance of lower rank is alive for that robot. Ranks
//! are unique per robot (an instance refuses to start on a taken rank), so with one consistent
//! view of liveliness at most one instance is active. Views agree when all hosts reach each
//! other through one router; the remaining window is a link lease after a partition, when the
//! isolated primary cannot reach the robot either. Standbys run the model on the same inputs
//! (hot standby), so a takeover needs no warm-up.

/// The liveliness name of an instance of `service` with `rank`: `forecaster-r1`.
pub fn instance_name(service: &str, rank: u32) -> String {
    format!("{service}-r{rank}")
}

/// The rank in an instance name of `service`, if it is one.
pub fn parse_instance(service: &str, name: &str) -> Option<u32> {
    name.strip_prefix(service)?.strip_prefix("-r")?.parse().ok()
}

/// Whether the instance with `rank` is active, given the ranks alive for a robot (its own
/// may or may not be among them).
pub fn is_active(rank: u32, alive_ranks: &[u32]) -> bool {
    alive_ranks.iter().all(|&r| r >= rank)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lowest_live_rank_is_the_only_active_one() {
        assert!(is_active(0, &[0, 1, 2]));
        assert!(!is_active(1, &[0, 1]));
        assert!(is_active(1, &[1, 2]));
        assert!(!is_active(2, &[1, 2]));
        assert!(is_active(3, &[]));
        // For any live set, exactly one member is active.
        for set in [vec![0u32, 1, 2], vec![2, 5], vec![7]] {
            assert_eq!(set.iter().filter(|&&r| is_active(r, &set)).count(), 1);
        }
    }

    #[test]
    fn instance_names_round_trip() {
        assert_eq!(instance_name("forecaster", 2), "forecaster-r2");
        assert_eq!(parse_instance("forecaster", "forecaster-r2"), Some(2));
        assert_eq!(parse_instance("forecaster", "forecaster"), None);
        assert_eq!(parse_instance("forecaster", "retargeter-r1"), None);
        assert_eq!(parse_instance("forecaster", "forecaster-rx"), None);
    }
}
