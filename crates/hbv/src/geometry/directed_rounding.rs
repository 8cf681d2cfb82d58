//! f64 values rounded to f32 in a chosen direction: the conservative bounds of the nearest-point
//! search (`proximity`) are computed in f64 and stored in f32, each rounded the way that keeps
//! it a bound (a lower bound down, an upper bound or an enclosure's extent up).

/// The largest f32 not above `x`.
pub(crate) fn f32_below(x: f64) -> f32 {
    let near = x as f32;
    if (near as f64) > x {
        near.next_down()
    } else {
        near
    }
}

/// The least f32 not below `x`.
pub(crate) fn f32_above(x: f64) -> f32 {
    let near = x as f32;
    if (near as f64) < x {
        near.next_up()
    } else {
        near
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounds_bracket_the_value_and_are_adjacent_floats() {
        for x in [
            0.0,
            1.0,
            0.1,
            -0.1,
            1e-40,
            -3e38,
            1.0 / 3.0,
            f64::from(f32::MAX),
        ] {
            let (lo, hi) = (f32_below(x), f32_above(x));
            assert!(f64::from(lo) <= x && x <= f64::from(hi), "{x}");
            assert!(lo == hi || lo.next_up() == hi, "{x}: {lo} {hi}");
        }
    }
}
