//! CDR payloads as ROS 2 sends them: a 4-byte encapsulation header (little- or big-endian
//! plain CDR), then the message.

use crate::msg::Message;
use byteorder::{BigEndian, LittleEndian};

/// Why bytes are not the message expected.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum CdrError {
    /// Shorter than the encapsulation header.
    #[error("{0} bytes: shorter than the 4-byte CDR header")]
    Short(usize),
    /// Not plain CDR (the header's representation id).
    #[error("representation {0:#06x} is not plain CDR (0x0000 big-endian, 0x0001 little-endian)")]
    Representation(u16),
    /// The body does not decode as the message.
    #[error("not a {name}: {message}")]
    Body {
        /// The message type.
        name: &'static str,
        /// What the decoder said.
        message: String,
    },
}

/// The message as a little-endian CDR payload.
pub fn to_bytes<M: Message>(m: &M) -> Vec<u8> {
    let mut out = vec![0x00, 0x01, 0x00, 0x00];
    // Serializing plain structs of numbers, strings and sequences into memory cannot fail.
    out.extend(cdr_encoding::to_vec::<M, LittleEndian>(m).unwrap_or_default());
    out
}

/// The message in a CDR payload of either byte order.
pub fn from_bytes<M: Message>(bytes: &[u8]) -> Result<M, CdrError> {
    let Some(body) = bytes.get(4..) else {
        return Err(CdrError::Short(bytes.len()));
    };
    let rep = u16::from_be_bytes([bytes[0], bytes[1]]);
    let result = match rep {
        0x0001 => cdr_encoding::from_bytes::<M, LittleEndian>(body),
        0x0000 => cdr_encoding::from_bytes::<M, BigEndian>(body),
        r => return Err(CdrError::Representation(r)),
    };
    result.map(|(m, _)| m).map_err(|e| CdrError::Body {
        name: M::NAME,
        message: e.to_string(),
    })
}
