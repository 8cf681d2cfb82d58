//! Output paths refused before a command's work, not after it.
//!
//! A command that measures for minutes and then cannot write its result (a missing folder, a
//! name the writer cannot encode) has wasted the minutes: `hbv build-compare --plot no/such/x.svg`
//! failed after measuring, with the drawing library's debug text. Each command that writes files
//! checks them here first, with the messages the write itself would give.

use std::io;
use std::path::Path;

use hbv::atomic_file::{check_writable, Replace};

/// What an output file is written as, for the check of its name.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OutputFormat {
    /// PNG images: renders, their passes, plots.
    Png,
    /// OpenEXR images (`hbv render --exr`).
    OpenExr,
}

impl OutputFormat {
    fn extension(self) -> &'static str {
        match self {
            OutputFormat::Png => "png",
            OutputFormat::OpenExr => "exr",
        }
    }

    fn name(self) -> &'static str {
        match self {
            OutputFormat::Png => "PNG",
            OutputFormat::OpenExr => "OpenEXR",
        }
    }
}

/// Checks that `path` can be written as [`hbv::atomic_file::write_atomically`] would write
/// it (not a directory; its folder exists and is a folder) and, for a `format`, that its name
/// ends in that format's extension, so that a `.svg` or `.jpg` name does not get a PNG under
/// it. A device or a pipe (`/dev/null`) is written into whatever its name.
pub fn check_output(path: &Path, format: Option<OutputFormat>) -> io::Result<()> {
    check_writable(path)?;
    let Some(format) = format else {
        return Ok(());
    };
    let in_place = std::fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir());
    let extension = path.extension().and_then(|e| e.to_str());
    if in_place || extension.is_some_and(|e| e.eq_ignore_ascii_case(format.extension())) {
        return Ok(());
    }
    Err(io::Error::new(
        io::ErrorKind::InvalidInput,
        format!(
            "cannot write {}: it is written as {}, so its name must end in .{}",
            path.display(),
            format.name(),
            format.extension()
        ),
    ))
}

/// What a command's `--force` means for its outputs: replace files that exist, or refuse them.
/// Refusing is decided when each output is put in place, atomically, so a file created while
/// the command works is not replaced either (a check before the work alone let it be).
pub fn replace_policy(force: bool) -> Replace {
    if force {
        Replace::Always
    } else {
        Replace::Never
    }
}

/// Checks a folder that a command creates (with its parents) and fills: it is a folder if it
/// exists, and otherwise the nearest existing folder above it is one.
pub fn check_output_folder(dir: &Path) -> io::Result<()> {
    let mut at = dir;
    loop {
        match std::fs::metadata(at) {
            Ok(m) if m.is_dir() => return Ok(()),
            Ok(_) => {
                return Err(io::Error::new(
                    io::ErrorKind::NotADirectory,
                    format!(
                        "cannot create {}: {} is not a directory",
                        dir.display(),
                        at.display()
                    ),
                ))
            }
            // `file/rays` is "not a directory" rather than "not found": look further up.
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::NotFound | io::ErrorKind::NotADirectory
                ) =>
            {
                match at.parent() {
                    Some(parent) if !parent.as_os_str().is_empty() => at = parent,
                    _ => return Ok(()),
                }
            }
            Err(e) => {
                return Err(io::Error::new(
                    e.kind(),
                    format!("cannot create {}: {e}", dir.display()),
                ))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_folders_and_formats_are_checked() {
        let dir = tempfile::tempdir().unwrap();
        let at = |name: &str| dir.path().join(name);
        std::fs::write(at("file"), "x").unwrap();
        check_output(&at("plot.png"), Some(OutputFormat::Png)).unwrap();
        check_output(&at("plot.PNG"), Some(OutputFormat::Png)).unwrap();
        check_output(&at("hits.npz"), None).unwrap();
        let message = |r: io::Result<()>| r.unwrap_err().to_string();
        assert!(
            message(check_output(&at("plot.svg"), Some(OutputFormat::Png)))
                .ends_with("plot.svg: it is written as PNG, so its name must end in .png")
        );
        assert!(
            message(check_output(&at("x.png"), Some(OutputFormat::OpenExr)))
                .ends_with("x.png: it is written as OpenEXR, so its name must end in .exr")
        );
        assert!(message(check_output(
            &at("no/such/plot.png"),
            Some(OutputFormat::Png)
        ))
        .ends_with("no/such does not exist"));
        assert!(
            message(check_output(&at("file/plot.png"), None)).ends_with("file is not a directory")
        );
        assert!(message(check_output(dir.path(), None)).ends_with("it is a directory"));
        #[cfg(unix)]
        check_output(Path::new("/dev/null"), Some(OutputFormat::Png)).unwrap();

        check_output_folder(&at("new/deeper")).unwrap();
        check_output_folder(dir.path()).unwrap();
        assert!(message(check_output_folder(&at("file/rays"))).ends_with("file is not a directory"));
    }
}
