//! base64 for glTF `data:` URIs, through the base64 crate: encoding with padding; decoding as
//! lenient as glTF files in the wild need (padding optional, ASCII whitespace skipped, and the
//! URL-safe alphabet taken as well as the standard one).

use base64::engine::{DecodePaddingMode, GeneralPurpose, GeneralPurposeConfig};
use base64::{alphabet, Engine as _};

/// Encodes `data` with padding (the standard alphabet).
pub fn encode(data: &[u8]) -> String {
    base64::engine::general_purpose::STANDARD.encode(data)
}

/// Decodes base64 text; padding is optional, ASCII whitespace is skipped, and a text written in
/// the URL-safe alphabet (`-` and `_`) is read in it.
pub fn decode(text: &str) -> Result<Vec<u8>, String> {
    // (Trailing bits that are not zero, "TWF=", were taken by the hand-written decoder before.)
    let config = GeneralPurposeConfig::new().with_decode_padding_mode(DecodePaddingMode::Indifferent).with_decode_allow_trailing_bits(true);
    let url_safe = text.bytes().any(|c| c == b'-' || c == b'_');
    let engine = GeneralPurpose::new(if url_safe { &alphabet::URL_SAFE } else { &alphabet::STANDARD }, config);
    let decoded = if text.bytes().any(|c| c.is_ascii_whitespace()) {
        engine.decode(text.bytes().filter(|c| !c.is_ascii_whitespace()).collect::<Vec<u8>>())
    } else {
        engine.decode(text)
    };
    decoded.map_err(|e| format!("invalid base64: {e}"))
}
