//! The error of a results file: the file, sample, box and field it is about.

use std::fmt;
use std::path::{Path, PathBuf};

/// A problem with a results file, located as precisely as possible.
#[derive(Debug, Clone, PartialEq)]
pub struct JsonError {
    /// The file (empty when parsing from memory).
    pub file: PathBuf,
    /// The sample token of the offending box, if any.
    pub sample: Option<String>,
    /// The offending box's index within its sample, if any.
    pub index: Option<usize>,
    /// The field, if any.
    pub field: Option<String>,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for JsonError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file.display())?;
        if let Some(s) = &self.sample {
            write!(f, ": sample '{s}'")?;
        }
        if let Some(i) = self.index {
            write!(f, ", box {i}")?;
        }
        if let Some(field) = &self.field {
            write!(f, ", field '{field}'")?;
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for JsonError {}

impl JsonError {
    /// A problem with the whole file.
    pub fn file(file: &Path, message: impl Into<String>) -> JsonError {
        JsonError {
            file: file.to_path_buf(),
            sample: None,
            index: None,
            field: None,
            message: message.into(),
        }
    }

    /// A problem with a field of box `index` of `sample`.
    pub fn field(
        file: &Path,
        sample: &str,
        index: usize,
        field: &str,
        message: impl Into<String>,
    ) -> JsonError {
        JsonError {
            sample: Some(sample.to_string()),
            index: Some(index),
            field: Some(field.to_string()),
            ..JsonError::file(file, message)
        }
    }
}
