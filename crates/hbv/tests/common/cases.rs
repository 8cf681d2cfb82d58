//! How many cases a property test runs: its own count, which a run can raise without editing
//! the tests. Shared by the library's unit tests (`lib.rs` includes this file) and the
//! integration tests (`common`).
//!
//! - `PROPTEST_CASES=N`: every property test runs `N` cases (proptest's own variable, which an
//!   explicit `with_cases` would otherwise override).
//! - `HBV_PROPTEST_SCALE=K`: every property test runs `K` times its own count (a soak run:
//!   rare inputs, such as an error scale that overflows f32, turn up sooner).
//!
//! The other `PROPTEST_*` variables (seed source, shrinking limits, …) keep proptest's meaning.

use proptest::test_runner::Config;

/// The configuration of a property test that runs `cases` cases by default (module notes).
/// The limits on rejected inputs (`prop_assume!`) grow with the case count, so that a soak run
/// is not aborted for rejecting as large a share of its inputs as a default run.
pub fn cases(cases: u32) -> Config {
    let scaled = scaled_cases(
        cases,
        std::env::var("PROPTEST_CASES").ok().as_deref(),
        std::env::var("HBV_PROPTEST_SCALE").ok().as_deref(),
    );
    let growth = scaled.div_ceil(cases.max(1)).max(1);
    let default = Config::default();
    Config {
        cases: scaled,
        max_global_rejects: default.max_global_rejects.saturating_mul(growth),
        max_local_rejects: default.max_local_rejects.saturating_mul(growth),
        ..default
    }
}

/// `cases`, replaced by `absolute` or multiplied by `scale` when either is given (saturating).
/// A value that is not a positive integer stops the test run with a message naming it.
fn scaled_cases(cases: u32, absolute: Option<&str>, scale: Option<&str>) -> u32 {
    let read = |name: &str, value: &str| -> u32 {
        match value.trim().parse::<u32>() {
            Ok(n) if n > 0 => n,
            _ => panic!("{name}={value:?}: expected a positive integer"),
        }
    };
    match (absolute, scale) {
        (Some(n), _) => read("PROPTEST_CASES", n),
        (None, Some(k)) => cases.saturating_mul(read("HBV_PROPTEST_SCALE", k)),
        (None, None) => cases,
    }
}

#[test]
fn case_counts_follow_the_environment() {
    assert_eq!(scaled_cases(200, None, None), 200);
    assert_eq!(scaled_cases(200, Some("7"), Some("3")), 7);
    assert_eq!(scaled_cases(200, None, Some("10")), 2000);
    assert_eq!(scaled_cases(u32::MAX, None, Some("2")), u32::MAX);
    assert!(std::panic::catch_unwind(|| scaled_cases(1, None, Some("0"))).is_err());
    assert!(std::panic::catch_unwind(|| scaled_cases(1, Some("many"), None)).is_err());
}
