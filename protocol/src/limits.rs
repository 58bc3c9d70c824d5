//! The validity domain: the ranges every value of a frame must lie in. The wire encoder, the wire
//! decoder and the results-file reader all check against these same limits, so what one accepts
//! the others accept too, and fused output can always be brought into the domain ([`clamp_std`]).
//! `docs/wire-format.md` lists them.

/// The most objects a frame may carry.
pub const MAX_OBJECTS: usize = 4096;
/// The most agents a fused frame's provenance may list (the fuser tracks no more at once).
pub const MAX_WINDOW_AGENTS: usize = 1024;
/// The longest agent name, in bytes.
pub const MAX_AGENT_NAME: usize = 64;
/// The largest payload a decoder looks at, in bytes (far above what `MAX_OBJECTS` objects take).
pub const MAX_PAYLOAD: usize = 1 << 20;
/// The largest message a Zenoh session of the project reassembles, in bytes: a frame of
/// [`MAX_PAYLOAD`] with room for its key, attachment and headers. Larger messages are dropped
/// by Zenoh before they take memory (its own default is 1 GiB).
pub const MAX_MESSAGE: usize = 2 << 20;
/// Smallest box size along any axis (m): one centimetre.
pub const SIZE_MIN: f64 = 0.01;
/// Largest box size along any axis (m).
pub const SIZE_MAX: f64 = 1000.0;
/// Largest |coordinate| of a centre or a frame origin in the map frame (m).
pub const COORD_MAX: f64 = 1e9;
/// Largest |velocity| along either axis (m/s).
pub const VEL_MAX: f64 = 100.0;
/// The wire's velocity step (m/s).
pub const VEL_STEP: f64 = 0.1;

/// True when a velocity component is finite and within [`VEL_MAX`] once quantized.
pub fn vel_in_range(v: f64) -> bool {
    v.is_finite() && ((v / VEL_STEP).round() * VEL_STEP).abs() <= VEL_MAX
}

/// Smallest standard deviation (m or rad): the floor of the logarithmic std code.
pub const STD_MIN: f64 = 1e-4;
/// Steps of the logarithmic std code per e-fold: std = STD_MIN exp((code - 1) / STD_PER_UNIT).
pub const STD_PER_UNIT: f64 = 500.0;
/// The largest std code: the one of 10 km (or 10^4 rad).
pub const STD_CODE_MAX: u16 = 9211;

/// The std a code stands for (code in 1..=[`STD_CODE_MAX`]).
pub fn std_of_code(code: u16) -> f64 {
    STD_MIN * ((code as f64 - 1.0) / STD_PER_UNIT).exp()
}

/// Largest standard deviation (m or rad): the std of [`STD_CODE_MAX`], about 10^4.
pub fn std_max() -> f64 {
    // Computed once: every std read from a file or the wire is checked against it.
    static MAX: std::sync::OnceLock<f64> = std::sync::OnceLock::new();
    *MAX.get_or_init(|| std_of_code(STD_CODE_MAX))
}

/// True when a std lies in [`STD_MIN`], [`std_max`] (and is not NaN).
pub fn std_in_range(s: f64) -> bool {
    (STD_MIN..=std_max()).contains(&s)
}

/// Brings a finite std into the domain: raised to [`STD_MIN`], lowered to [`std_max`].
/// NaN stays NaN (the caller rejects it).
pub fn clamp_std(s: f64) -> f64 {
    s.clamp(STD_MIN, std_max())
}

/// True when a size lies in [`SIZE_MIN`], [`SIZE_MAX`] once rounded to centimetres.
pub fn size_in_range(s: f64) -> bool {
    // Rounding halves away from zero, a whole number of centimetres n is what [n - 0.5, n + 0.5)
    // rounds to: bounds on the unrounded value, without a call to round.
    (SIZE_MIN * 100.0 - 0.5..SIZE_MAX * 100.0 + 0.5).contains(&(s * 100.0))
}

/// True when a coordinate is finite and |x| <= [`COORD_MAX`] once rounded to centimetres.
pub fn coord_in_range(x: f64) -> bool {
    // As in `size_in_range`: |round(v)| <= n is |v| < n + 0.5 (false for NaN and infinities).
    (x * 100.0).abs() < COORD_MAX * 100.0 + 0.5
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_std_code_covers_its_range_exactly() {
        assert_eq!(std_of_code(1), STD_MIN);
        let max = std_max();
        assert!((max - 1e4).abs() / 1e4 < 1e-3, "{max}");
        assert!(std_in_range(STD_MIN) && std_in_range(max));
        assert!(!std_in_range(STD_MIN * 0.999) && !std_in_range(max * 1.001));
        assert!(!std_in_range(f64::NAN));
        assert_eq!(clamp_std(1e-300), STD_MIN);
        assert_eq!(clamp_std(1e300), max);
    }

    #[test]
    fn the_bounds_are_the_rounded_values_bounds() {
        let rounded_size =
            |s: f64| (SIZE_MIN * 100.0..=SIZE_MAX * 100.0).contains(&(s * 100.0).round());
        let rounded_coord =
            |x: f64| x.is_finite() && (x * 100.0).round().abs() <= COORD_MAX * 100.0;
        let edges = [
            0.0,
            0.005,
            0.01,
            1000.0,
            1000.005,
            1e9,
            1e9 + 0.005,
            1e9 + 0.01,
        ];
        let mut values = vec![
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::MIN_POSITIVE,
        ];
        for e in edges {
            let mut below = e;
            let mut above = e;
            for _ in 0..4 {
                values.extend([below, above, -below, -above]);
                below = below.next_down();
                above = above.next_up();
            }
        }
        values.extend((0..10_000).map(|i| (i as f64 * 0.618_034).fract() * 1e3 * (i % 7) as f64));
        for v in values {
            assert_eq!(size_in_range(v), rounded_size(v), "size {v:e}");
            assert_eq!(coord_in_range(v), rounded_coord(v), "coordinate {v:e}");
        }
    }

    #[test]
    fn sizes_and_coordinates() {
        assert!(size_in_range(0.01) && size_in_range(1000.0) && size_in_range(0.006));
        assert!(!size_in_range(0.004) && !size_in_range(1000.01) && !size_in_range(f64::NAN));
        assert!(
            coord_in_range(-1e9) && !coord_in_range(1.0001e9) && !coord_in_range(f64::INFINITY)
        );
    }
}
