//! The error of the noise, faults and stated-std settings a command line or a scenario gives.

use v2x_protocol::{InvalidValue, StdSettingError};

/// A noise, faults or stated-std setting that cannot be read.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("invalid {what} '{spec}': {problem}")]
pub struct SpecError {
    /// Which setting (`noise`, `faults`, `stated std`).
    pub what: &'static str,
    /// The setting as given.
    pub spec: String,
    /// What is wrong with it.
    pub problem: Problem,
}

/// What is wrong with a setting.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Problem {
    /// A part that is not `KEY=VALUE`.
    #[error("'{part}' is not KEY=VALUE (keys: {})", keys.join(", "))]
    NotKeyValue {
        /// The part.
        part: String,
        /// The keys the setting takes.
        keys: Vec<&'static str>,
    },
    /// A key that does not exist.
    #[error("unknown key '{key}' (keys: {})", keys.join(", "))]
    UnknownKey {
        /// The key.
        key: String,
        /// The keys the setting takes.
        keys: Vec<&'static str>,
    },
    /// A value outside its domain.
    #[error(transparent)]
    Value(#[from] InvalidValue),
    /// Not of any form the setting takes.
    #[error("expected {0}")]
    Form(&'static str),
}

impl SpecError {
    /// `spec`, given as a `what`, has `problem`.
    pub fn new(what: &'static str, spec: &str, problem: impl Into<Problem>) -> SpecError {
        SpecError {
            what,
            spec: spec.to_string(),
            problem: problem.into(),
        }
    }

    /// A std that [`v2x_protocol::parse_std`] refused, in a setting whose forms are `forms`.
    pub fn std(what: &'static str, spec: &str, e: StdSettingError, forms: &'static str) -> Self {
        let problem = match e {
            StdSettingError::Form(_) => Problem::Form(forms),
            StdSettingError::OutOfRange(s) => Problem::Value(InvalidValue::new(
                "each std",
                format!(
                    "in [{}, {:.0}] (metres, metres, degrees)",
                    v2x_protocol::limits::STD_MIN,
                    v2x_protocol::limits::std_max()
                ),
                s,
            )),
        };
        SpecError::new(what, spec, problem)
    }
}
