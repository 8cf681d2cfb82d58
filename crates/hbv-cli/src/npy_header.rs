//! The `.npy` header at the start of an archive member, read with a one-line reason when it is
//! not one.
//!
//! `ndarray-npy` parses the header, but its errors are for programmers: a syntax error in the
//! header's dictionary is a six-line parser diagram, and a header length past the member's end
//! is "I/O error: failed to fill whole buffer" (after allocating the declared length, up to
//! 4 GiB). The fixed prefix (magic string, version, header length) is therefore checked here
//! against the member's bytes first, and the parser's errors are put in words that say what is
//! wrong with the header.
//!
//! Layout (NumPy's `format.py`, versions 1.0 to 3.0): `\x93NUMPY`, major and minor version
//! bytes, the header length (2 bytes little-endian in 1.0, 4 in 2.0 and 3.0), then that many
//! bytes of a Python dict literal ending in a newline.

use ndarray_npy::npy::header::{Header, ParseHeaderError, ReadHeaderError};

const MAGIC: &[u8] = b"\x93NUMPY";

/// Most characters of a header value quoted in a message, so a line stays a line.
const MAX_QUOTED: usize = 60;

/// Reads the `.npy` header at the start of `member` (the whole member's bytes); the error is a
/// reason in words, for a message that already names the file and the member.
pub(crate) fn read_npy_header(member: &[u8]) -> Result<Header, String> {
    check_prefix(member)?;
    Header::from_reader(&mut &member[..]).map_err(|e| reason(&e))
}

/// Checks the magic string, the version and that the declared header fits in the member.
fn check_prefix(member: &[u8]) -> Result<(), String> {
    let len = member.len();
    if !member.starts_with(MAGIC) {
        return Err("not a .npy array (it does not start with the .npy magic string)".into());
    }
    let Some(&[major, minor]) = member.get(6..8) else {
        return Err(format!(
            "the .npy header is cut short: the member holds only {len} bytes"
        ));
    };
    let width = match (major, minor) {
        (1, 0) => 2,
        (2, 0) | (3, 0) => 4,
        _ => {
            return Err(format!(
                ".npy format version {major}.{minor} is not supported (1.0, 2.0 and 3.0 are)"
            ))
        }
    };
    let Some(field) = member.get(8..8 + width) else {
        return Err(format!(
            "the .npy header is cut short: the member holds only {len} bytes"
        ));
    };
    let declared = field
        .iter()
        .rev()
        .fold(0u64, |n, &b| (n << 8) | u64::from(b));
    let available = (len - 8 - width) as u64;
    if declared > available {
        return Err(format!(
            "the .npy header says it is {declared} bytes long, longer than the member \
             ({available} bytes after its {}-byte prefix)",
            8 + width
        ));
    }
    Ok(())
}

/// The parser's error in words.
fn reason(error: &ReadHeaderError) -> String {
    let parse = match error {
        // The prefix was checked, so this is the dictionary's bytes running out.
        ReadHeaderError::Io(e) => return format!("the .npy header is cut short: {e}"),
        ReadHeaderError::Parse(p) => p,
    };
    match parse {
        ParseHeaderError::MagicString => {
            "not a .npy array (it does not start with the .npy magic string)".into()
        }
        ParseHeaderError::Version { major, minor } => {
            format!(".npy format version {major}.{minor} is not supported")
        }
        ParseHeaderError::HeaderLengthOverflow(n) => {
            format!("the .npy header says it is {n} bytes long, more than this machine addresses")
        }
        ParseHeaderError::NonAscii => {
            "the .npy header has non-ASCII characters (allowed only in .npy format 3.0)".into()
        }
        ParseHeaderError::Utf8Parse(e) => format!("the .npy header is not UTF-8 text: {e}"),
        ParseHeaderError::MissingNewline => "the .npy header does not end with a newline".into(),
        ParseHeaderError::DictParse(_) => "the .npy header is not a Python dict literal".into(),
        ParseHeaderError::MetaNotDict(value) => format!(
            "the .npy header is not a Python dict but {}",
            quoted(&value.to_string())
        ),
        ParseHeaderError::UnknownKey(key) => format!(
            "the .npy header has an unknown key {} (expected 'descr', 'fortran_order' and \
             'shape')",
            quoted(&key.to_string())
        ),
        // ndarray-npy 0.10 spells the missing shape key "shaper".
        ParseHeaderError::MissingKey(key) => format!(
            "the .npy header has no '{}' key",
            if key == "shaper" { "shape" } else { key }
        ),
        ParseHeaderError::IllegalValue { key, value } => {
            let expected = match key.as_str() {
                "shape" => "a tuple of non-negative integers",
                "fortran_order" => "True or False",
                _ => "another value",
            };
            format!(
                "the .npy header's '{key}' is {}, expected {expected}",
                quoted(&value.to_string())
            )
        }
    }
}

/// `text` on one line and at most [`MAX_QUOTED`] characters (cut with `...`).
fn quoted(text: &str) -> String {
    let one_line: String = text
        .chars()
        .map(|c| if c.is_control() { ' ' } else { c })
        .collect();
    if one_line.chars().count() <= MAX_QUOTED {
        one_line
    } else {
        let cut: String = one_line.chars().take(MAX_QUOTED).collect();
        format!("{cut}...")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A version 1.0 member with header text `dict` (newline added) and no data.
    fn member(dict: &str) -> Vec<u8> {
        let text = format!("{dict}\n");
        let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
        bytes.extend((text.len() as u16).to_le_bytes());
        bytes.extend(text.as_bytes());
        bytes
    }

    #[test]
    fn a_good_header_reads() {
        let h = read_npy_header(&member(
            "{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3), }",
        ))
        .unwrap();
        assert_eq!(h.shape, [2, 3]);
    }

    #[test]
    fn every_bad_header_is_one_line_saying_what_is_wrong() {
        let long_len = {
            let mut m = member("{}");
            m[8..10].copy_from_slice(&u16::MAX.to_le_bytes());
            m
        };
        let cases: [(Vec<u8>, &str); 10] = [
            (
                b"PK garbage".to_vec(),
                "does not start with the .npy magic string",
            ),
            (
                b"\x93NUMPY\x01".to_vec(),
                "the .npy header is cut short: the member holds only 7",
            ),
            (
                b"\x93NUMPY\x09\x00\x10\x00".to_vec(),
                ".npy format version 9.0 is not supported",
            ),
            (
                long_len,
                "the .npy header says it is 65535 bytes long, longer than the member (3 bytes \
                 after its 10-byte prefix)",
            ),
            (
                member("{'descr': '<f4', 'fortran_"),
                "the .npy header is not a Python dict literal",
            ),
            (
                member("[1, 2]"),
                "the .npy header is not a Python dict but [1, 2]",
            ),
            (
                member("{'descr': '<f4', 'fortran_order': False, 'shape': (-8, 3), }"),
                "the .npy header's 'shape' is (-8, 3), expected a tuple of non-negative integers",
            ),
            (
                member("{'descr': '<f4', 'fortran_order': False, }"),
                "the .npy header has no 'shape' key",
            ),
            (
                member("{'descr': '<f4', 'fortran_order': False, 'shape': (3,), 'x': 1}"),
                "the .npy header has an unknown key 'x'",
            ),
            (member("{'descr': '\u{e9}'}"), "non-ASCII characters"),
        ];
        for (bytes, expected) in cases {
            let reason = read_npy_header(&bytes).unwrap_err();
            assert!(reason.contains(expected), "{reason}");
            assert!(!reason.contains('\n'), "{reason}");
        }
    }

    #[test]
    fn long_values_are_cut_to_one_short_line() {
        let shape = format!("({})", "-1, ".repeat(50));
        let reason = read_npy_header(&member(&format!(
            "{{'descr': '<f4', 'fortran_order': False, 'shape': {shape}}}"
        )))
        .unwrap_err();
        assert!(
            reason.ends_with("..., expected a tuple of non-negative integers"),
            "{reason}"
        );
    }
}
