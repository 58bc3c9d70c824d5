//! What an agent says of its own errors: the stds its boxes carry, which need not be the ones
//! its noise has (an over- or underconfident detector, or one that states none).

use crate::spec::SpecError;
use std::fmt;
use std::str::FromStr;
use v2x_protocol::{parse_std, InvalidValue, Uncertainty};

/// The stds an agent states with each box.
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub enum Stated {
    /// Its noise's own stds (the paper's setting).
    #[default]
    Honest,
    /// Its noise's own stds times this factor (`x6`: six times too wide, `x0.1667` six times
    /// too narrow), velocity included.
    Scaled(f64),
    /// These stds whatever its noise (a profile name or POS,SIZE,YAW_DEG); the velocity std
    /// scaled as the centre's.
    Fixed(Uncertainty),
    /// None: results files leave the std fields out, as most detectors' do (the boxes in
    /// memory and on the wire keep the honest ones).
    Nothing,
}

impl Stated {
    /// The box stds and the velocity std an agent with noise stds `std` and velocity std
    /// `velocity` states.
    pub fn apply(self, std: Uncertainty, velocity: f64) -> (Uncertainty, f64) {
        match self {
            Stated::Honest | Stated::Nothing => (std, velocity),
            Stated::Scaled(k) => (
                Uncertainty::from_array(std.as_array().map(|s| s * k)),
                velocity * k,
            ),
            Stated::Fixed(u) => (u, velocity * u.pos[0] / std.pos[0]),
        }
    }
}

impl FromStr for Stated {
    type Err = SpecError;
    /// `honest`, `none`, `xK` (K > 0), a profile name or POS,SIZE,YAW_DEG.
    fn from_str(s: &str) -> Result<Self, SpecError> {
        match s {
            "honest" => return Ok(Stated::Honest),
            "none" => return Ok(Stated::Nothing),
            _ => {}
        }
        if let Some(k) = s.strip_prefix('x') {
            return match k.parse::<f64>() {
                Ok(k) if k > 0.0 && k.is_finite() => Ok(Stated::Scaled(k)),
                _ => Err(SpecError::new(
                    "stated std",
                    s,
                    InvalidValue::new("the factor K of xK", "> 0", k),
                )),
            };
        }
        parse_std(s).map(Stated::Fixed).map_err(|e| {
            let forms = "honest, none, xK (the noise's own stds times K), mild, moderate, large \
                         or POS,SIZE,YAW_DEG";
            SpecError::std("stated std", s, e, forms)
        })
    }
}

impl fmt::Display for Stated {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Stated::Honest => f.write_str("honest"),
            Stated::Nothing => f.write_str("none"),
            Stated::Scaled(k) => write!(f, "x{k}"),
            Stated::Fixed(u) => write!(f, "{},{},{}", u.pos[0], u.size[0], u.yaw.to_degrees()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use v2x_protocol::NoiseProfile;

    #[test]
    fn parse_and_apply() {
        let large = NoiseProfile::Large.std();
        let (u, v) = "x0.5".parse::<Stated>().unwrap().apply(large, 1.0);
        assert_eq!((u.pos, u.size, v), ([1.5; 3], [0.5; 3], 0.5));
        let (u, v) = "mild".parse::<Stated>().unwrap().apply(large, 1.0);
        assert_eq!((u, v), (NoiseProfile::Mild.std(), 1.0 / 6.0));
        assert_eq!("none".parse::<Stated>(), Ok(Stated::Nothing));
        assert_eq!(
            "honest".parse::<Stated>().unwrap().apply(large, 1.0),
            (large, 1.0)
        );
        for bad in ["x0", "x-1", "xx", "loud", "1,2"] {
            assert!(bad.parse::<Stated>().is_err(), "{bad}");
        }
        assert_eq!(Stated::Scaled(6.0).to_string(), "x6");
    }
}
