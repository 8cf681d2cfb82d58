//! Parsers of numeric flags (clap `value_parser`s): each takes only the values its flag can
//! use and, for any other, says which it takes. Clap names the flag and the value given:
//! `invalid value 'nan' for '--lambda <LAMBDA>': expected a finite number from 0.001 to 1024`.
//!
//! Every flag takes values that look like negative numbers (`main.rs`,
//! `negative_numbers_as_values`), so that `--lambda -1` is refused for its value, not read as
//! an unknown flag `-1`.

/// The most rays a `--rays` flag may ask for: 2^27, far past any benchmark (`hbv bench`'s three
/// sets of them take 13 GB), and small enough that no count can overflow an allocation.
pub const MAX_RAYS: usize = 1 << 27;

/// The grid density λ that `--lambda` takes: below 0.001 the grid takes 0.001, and above 1024
/// no axis can have more cells (`GridShape` makes at most λ · N^(1/3), and 1024, along one).
const LAMBDA_RANGE: (f64, f64) = (0.001, 1024.0);

/// The largest `--displacement`, in scene diagonals: ten diagonals move every triangle far out
/// of the scene already; much larger offsets only risk leaving f32's range.
const MAX_DISPLACEMENT: f64 = 10.0;

/// `--rays N`: 1 to [`MAX_RAYS`], refused before anything is allocated.
pub fn ray_count(arg: &str) -> Result<usize, String> {
    let expected = || format!("expected 1 to {MAX_RAYS} rays per set");
    let n: i128 = arg.trim().parse().map_err(|_| expected())?;
    if !(1..=MAX_RAYS as i128).contains(&n) {
        return Err(expected());
    }
    Ok(n as usize)
}

/// A seed: any whole number from 0 to 2^64 − 1.
pub fn seed(arg: &str) -> Result<u64, String> {
    arg.trim()
        .parse()
        .map_err(|_| format!("expected a whole number from 0 to {}", u64::MAX))
}

/// `--lambda`: a grid density λ in [`LAMBDA_RANGE`].
pub fn grid_density(arg: &str) -> Result<f64, String> {
    finite_in(arg, LAMBDA_RANGE.0, LAMBDA_RANGE.1)
}

/// `--displacement`: a fraction of the scene's diagonal from 0 to [`MAX_DISPLACEMENT`].
pub fn displacement(arg: &str) -> Result<f32, String> {
    finite_in(arg, 0.0, MAX_DISPLACEMENT).map(|d| d as f32)
}

/// A finite number from `lo` to `hi` (NaN and the infinities are refused by name, as
/// `f64::from_str` takes them).
fn finite_in(arg: &str, lo: f64, hi: f64) -> Result<f64, String> {
    let expected = format!("expected a finite number from {lo} to {hi}");
    match arg.trim().parse::<f64>() {
        Ok(x) if x.is_finite() && (lo..=hi).contains(&x) => Ok(x),
        Ok(x) if !x.is_finite() => Err(format!("{expected}, not {x}")),
        _ => Err(expected),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_values_the_flag_can_use_are_taken() {
        assert_eq!(ray_count("1"), Ok(1));
        assert_eq!(ray_count("134217728"), Ok(MAX_RAYS));
        for bad in ["0", "-1", "134217729", "18446744073709551616", "1e3", "x"] {
            assert_eq!(
                ray_count(bad),
                Err("expected 1 to 134217728 rays per set".into()),
                "{bad}"
            );
        }
        assert_eq!(seed("18446744073709551615"), Ok(u64::MAX));
        assert!(seed("-1")
            .unwrap_err()
            .contains("0 to 18446744073709551615"));
        assert_eq!(grid_density("2"), Ok(2.0));
        assert_eq!(grid_density("0.001"), Ok(0.001));
        for bad in ["0", "-1", "1025", "1e300"] {
            assert_eq!(
                grid_density(bad),
                Err("expected a finite number from 0.001 to 1024".into()),
                "{bad}"
            );
        }
        assert_eq!(
            grid_density("nan"),
            Err("expected a finite number from 0.001 to 1024, not NaN".into())
        );
        assert_eq!(displacement("0"), Ok(0.0));
        assert_eq!(displacement("0.05"), Ok(0.05));
        assert_eq!(
            displacement("-inf"),
            Err("expected a finite number from 0 to 10, not -inf".into())
        );
        assert!(displacement("-0.5").is_err());
        assert!(displacement("11").is_err());
    }
}
