//! The errors of values read from the command line and files: a name outside a closed set
//! (classes, profiles, methods, splits...) and a field outside its domain.

use std::fmt;

/// A name that is none of the known ones.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub struct UnknownName {
    /// What was being named (`class`, `method`...).
    pub what: &'static str,
    /// The name given.
    pub given: String,
    /// The names accepted.
    pub expected: Vec<&'static str>,
}

impl UnknownName {
    /// `given` is not a known `what`; `expected` are the names that are.
    pub fn new(
        what: &'static str,
        given: &str,
        expected: impl IntoIterator<Item = &'static str>,
    ) -> UnknownName {
        UnknownName {
            what,
            given: given.to_string(),
            expected: expected.into_iter().collect(),
        }
    }
}

impl fmt::Display for UnknownName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "unknown {} '{}' (expected one of: {})",
            self.what,
            self.given,
            self.expected.join(", ")
        )
    }
}

/// A field whose value is outside what it accepts.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{field} must be {expected} (got {got})")]
pub struct InvalidValue {
    /// The field (`latency_ms`, `latitude`...).
    pub field: String,
    /// What it accepts.
    pub expected: String,
    /// What it was given.
    pub got: String,
}

impl InvalidValue {
    /// `field` must be `expected` but is `got`.
    pub fn new(
        field: impl Into<String>,
        expected: impl Into<String>,
        got: impl ToString,
    ) -> InvalidValue {
        InvalidValue {
            field: field.into(),
            expected: expected.into(),
            got: got.to_string(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_what_was_given_and_what_is_known() {
        let e = UnknownName::new("split", "dev", ["train", "val"]);
        assert_eq!(
            e.to_string(),
            "unknown split 'dev' (expected one of: train, val)"
        );
    }

    #[test]
    fn names_the_field_its_domain_and_the_value() {
        let e = InvalidValue::new("drop_rate", "in [0, 1]", 1.5);
        assert_eq!(e.to_string(), "drop_rate must be in [0, 1] (got 1.5)");
    }
}
