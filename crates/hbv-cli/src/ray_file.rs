//! Reading ray files: `.npz` archives with members `origins`, `directions` and optionally `tmin`,
//! `tmax` (see `docs/RAYS.md`).

use std::fmt;
use std::fs::File;
use std::io::{self, BufReader, Read, Seek};
use std::path::{Path, PathBuf};

use glam::Vec3;
use hbv::geometry::Ray;
use ndarray::ArrayD;
use ndarray_npy::{ReadNpyError, ReadNpyExt, ReadNpzError, ReadableElement};
use zip::result::ZipError;
use zip::{CompressionMethod, ZipArchive};

use crate::npy_header::read_npy_header;
use crate::npz_writer::NpzStream;

/// An error reading an `.npz` ray, hit or occlusion file: the file, the member if one is to
/// blame, and why.
#[derive(Debug)]
pub struct RayFileError {
    path: PathBuf,
    member: Option<String>,
    reason: Reason,
}

#[derive(Debug)]
pub(crate) enum Reason {
    Open(io::Error),
    NotNpz(ReadNpzError),
    Missing {
        alias: Option<&'static str>,
        present: Vec<String>,
    },
    Shape {
        shape: Vec<usize>,
        expected: String,
    },
    Length {
        len: usize,
        other: String,
        other_len: usize,
    },
    Dtype {
        descr: String,
        accepted: &'static str,
    },
    Invalid(String),
}

impl RayFileError {
    /// An error about `path`, and about its `member` where one is given.
    pub(crate) fn new(path: &Path, member: Option<&str>, reason: Reason) -> Self {
        Self {
            path: path.to_owned(),
            member: member.map(str::to_owned),
            reason,
        }
    }

    /// The file that could not be read.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The member of the archive at fault, if the error is about one.
    pub fn member(&self) -> Option<&str> {
        self.member.as_deref()
    }
}

impl fmt::Display for RayFileError {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        let path = self.path.display();
        let member = self.member.as_deref().unwrap_or("");
        match &self.reason {
            Reason::Open(e) => write!(f, "cannot open {path}: {e}"),
            Reason::NotNpz(e) => write!(f, "{path} is not an .npz archive: {e}"),
            Reason::Missing { alias, present } => write!(
                f,
                "{path}: no member `{member}`{} (members: {})",
                alias.map_or(String::new(), |a| format!(" or `{a}`")),
                if present.is_empty() {
                    "none".to_owned()
                } else {
                    present.join(", ")
                }
            ),
            Reason::Shape { shape, expected } => write!(
                f,
                "{path}: {member} has shape {}, expected {expected}",
                shape_str(shape)
            ),
            Reason::Length {
                len,
                other,
                other_len,
            } => write!(
                f,
                "{path}: {member} has {len} rows but {other} has {other_len}"
            ),
            Reason::Dtype { descr, accepted } => write!(
                f,
                "{path}: {member} has unsupported dtype {descr}; accepted: {accepted}"
            ),
            Reason::Invalid(why) => write!(f, "{path}: {member}: {why}"),
        }
    }
}

/// The message includes the cause's, so the cause is not also given as the `source()`: error
/// reports that print the chain (anyhow's `{:#}`) would repeat it.
impl std::error::Error for RayFileError {}

/// Why an archive member's bytes could not be read.
#[derive(Debug)]
enum MemberProblem {
    /// The archive declares more bytes than can be held in memory: a compressed member may
    /// expand to a thousand times its stored size, so the declared size is reserved before
    /// anything is decompressed.
    TooLarge(u64),
    /// The member decompresses to more bytes than the archive declares for it.
    LongerThanDeclared(u64),
    Unreadable(io::Error),
}

impl fmt::Display for MemberProblem {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        match self {
            MemberProblem::TooLarge(size) => write!(
                f,
                "the archive declares it {size} bytes long uncompressed, more than this machine \
                 can hold"
            ),
            MemberProblem::LongerThanDeclared(size) => write!(
                f,
                "it decompresses to more than the {size} bytes the archive declares for it"
            ),
            MemberProblem::Unreadable(e) => write!(f, "cannot read: {e}"),
        }
    }
}

/// Reads `member` into `bytes`: never more than its declared uncompressed size (memory is
/// reserved for that size first, and refused cleanly if it cannot be had), and an error if the
/// data runs past it. A small compressed member declaring, or decompressing to, gigabytes
/// would otherwise take the machine's memory before any check could see it.
fn read_declared(
    declared: u64,
    member: impl Read,
    bytes: &mut Vec<u8>,
) -> Result<(), MemberProblem> {
    let size = usize::try_from(declared).map_err(|_| MemberProblem::TooLarge(declared))?;
    bytes
        .try_reserve_exact(size)
        .map_err(|_| MemberProblem::TooLarge(declared))?;
    // One byte past the declared size tells a member that runs past it.
    let read = member
        .take(declared.saturating_add(1))
        .read_to_end(bytes)
        .map_err(MemberProblem::Unreadable)?;
    if read as u64 > declared {
        return Err(MemberProblem::LongerThanDeclared(declared));
    }
    Ok(())
}

/// A shape as NumPy prints it: `(5,)`, `(5, 3)`, `()`.
pub(crate) fn shape_str(shape: &[usize]) -> String {
    match shape {
        [n] => format!("({n},)"),
        _ => {
            let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
            format!("({})", dims.join(", "))
        }
    }
}

/// A NumPy dtype descriptor, as the `.npy` header spells it (`'<i4'`), with its name where it is
/// a common one: `int32 ('<i4')`.
pub(crate) fn dtype_str(descr: String) -> String {
    let code = descr
        .trim_matches('\'')
        .trim_start_matches(['<', '>', '|', '=']);
    let name = match code {
        "b1" | "?" => "bool",
        "i1" => "int8",
        "i2" => "int16",
        "i4" => "int32",
        "i8" => "int64",
        "u1" => "uint8",
        "u2" => "uint16",
        "u4" => "uint32",
        "u8" => "uint64",
        "f2" => "float16",
        "f4" => "float32",
        "f8" => "float64",
        "f16" => "float128",
        _ => return descr,
    };
    format!("{name} ({descr})")
}

/// Where an archive member's bytes lie in the file.
pub(crate) struct MemberPlace {
    /// Deflated (`numpy.savez_compressed`), else stored (`numpy.savez`).
    pub(crate) deflated: bool,
    /// Offset of the member's first stored byte in the file.
    pub(crate) data_start: u64,
    /// Bytes it takes in the file.
    pub(crate) stored_size: u64,
    /// Bytes it holds uncompressed, as the archive declares.
    pub(crate) size: u64,
    /// CRC-32 of the uncompressed bytes, as the archive declares.
    pub(crate) crc32: u32,
}

/// Anything an archive can be read from: a file, or bytes in memory.
trait ReadSeek: Read + Seek {}
impl<T: Read + Seek> ReadSeek for T {}

/// An open `.npz` archive, for reading members with errors that name the file and the member.
///
/// Members are read through the zip archive directly (not `NpzReader`) so that an `.npy`
/// header is checked against the data that follows it before anything is allocated: a header
/// may declare any shape, and `ndarray-npy` allocates the declared size up front.
pub(crate) struct Archive {
    path: PathBuf,
    zip: ZipArchive<Box<dyn ReadSeek>>,
    /// Member names as stored, and as NumPy lists them (without a `.npy` suffix).
    stored: Vec<String>,
    names: Vec<String>,
}

impl Archive {
    /// Opens `path` and lists its members (names without their `.npy` suffix).
    pub(crate) fn open(path: &Path) -> Result<Self, RayFileError> {
        let open_error = |e| RayFileError {
            path: path.to_owned(),
            member: None,
            reason: Reason::Open(e),
        };
        let file = File::open(path).map_err(open_error)?;
        // A directory opens on Unix; reading it would fail with a bare "i/o error" in zip.
        if file.metadata().is_ok_and(|m| m.is_dir()) {
            return Err(open_error(io::Error::new(
                io::ErrorKind::IsADirectory,
                "it is a directory",
            )));
        }
        Self::from_reader(path, BufReader::new(file))
    }

    /// Reads an archive from `reader`; `path` names it in errors.
    pub(crate) fn from_reader(
        path: &Path,
        reader: impl Read + Seek + 'static,
    ) -> Result<Self, RayFileError> {
        let error = |e: ZipError| RayFileError {
            path: path.to_owned(),
            member: None,
            reason: Reason::NotNpz(ReadNpzError::from(e)),
        };
        let reader: Box<dyn ReadSeek> = Box::new(reader);
        let zip = ZipArchive::new(reader).map_err(error)?;
        let stored: Vec<String> = (0..zip.len())
            .filter_map(|i| zip.name_for_index(i).map(str::to_owned))
            .collect();
        let names = stored
            .iter()
            .map(|n| n.strip_suffix(".npy").unwrap_or(n).to_owned())
            .collect();
        Ok(Self {
            path: path.to_owned(),
            zip,
            stored,
            names,
        })
    }

    /// The name member `name` is stored under: `name`, else `name.npy`, as NumPy looks it up.
    fn stored_name(&self, name: &str) -> String {
        if self.stored.iter().any(|n| n == name) {
            name.to_owned()
        } else {
            format!("{name}.npy")
        }
    }

    /// The bytes of member `name`.
    fn member_bytes(&mut self, name: &str) -> Result<Vec<u8>, RayFileError> {
        let stored = self.stored_name(name);
        let mut bytes = Vec::new();
        let read = self
            .zip
            .by_name(&stored)
            .map_err(|e| MemberProblem::Unreadable(io::Error::other(e)))
            .and_then(|member| read_declared(member.size(), member, &mut bytes));
        match read {
            Ok(()) => Ok(bytes),
            Err(problem) => Err(self.error(name, Reason::Invalid(problem.to_string()))),
        }
    }

    /// Where member `name` lies in the file, for reading it in place ([`MemberPlace`]).
    pub(crate) fn locate(&mut self, name: &str) -> Result<MemberPlace, RayFileError> {
        if !self.has(name) {
            return Err(self.missing(name));
        }
        let stored = self.stored_name(name);
        let place = match self.zip.by_name(&stored) {
            Ok(member) if member.encrypted() => Err("it is encrypted".to_owned()),
            Ok(member) => match member.compression() {
                method @ (CompressionMethod::Stored | CompressionMethod::Deflated) => {
                    Ok(MemberPlace {
                        deflated: method == CompressionMethod::Deflated,
                        data_start: member.data_start(),
                        stored_size: member.compressed_size(),
                        // A stored member is the bytes it takes, whatever size the
                        // archive declares uncompressed (as the zip crate reads it).
                        size: if method == CompressionMethod::Stored {
                            member.compressed_size()
                        } else {
                            member.size()
                        },
                        crc32: member.crc32(),
                    })
                }
                method => Err(format!(
                    "compression method {method} is not supported (stored and deflated are)"
                )),
            },
            Err(e) => Err(format!("cannot read: {e}")),
        };
        place.map_err(|why| self.error(name, Reason::Invalid(why)))
    }

    /// The file the archive was opened from.
    pub(crate) fn path(&self) -> &Path {
        &self.path
    }

    pub(crate) fn error(&self, member: &str, reason: Reason) -> RayFileError {
        RayFileError {
            path: self.path.clone(),
            member: Some(member.to_owned()),
            reason,
        }
    }

    /// Whether the archive has a member `name` (stored as `name` or `name.npy`).
    pub(crate) fn has(&self, name: &str) -> bool {
        self.names.iter().any(|n| n == name)
    }

    /// The error for a required member that is absent.
    pub(crate) fn missing(&self, name: &str) -> RayFileError {
        self.error(
            name,
            Reason::Missing {
                alias: None,
                present: self.names.clone(),
            },
        )
    }

    /// Reads member `name` with element type `T`; the inner error is the member's dtype where it is
    /// not `T`'s.
    fn try_read<T: ReadableElement>(
        &mut self,
        name: &str,
    ) -> Result<Result<ArrayD<T>, String>, RayFileError> {
        if !self.has(name) {
            return Err(self.missing(name));
        }
        let bytes = self.member_bytes(name)?;
        let header =
            read_npy_header(&bytes).map_err(|why| self.error(name, Reason::Invalid(why)))?;
        // Every element takes at least one byte: a header declaring more elements than there
        // are bytes lies, and must not make the reader allocate what it declares.
        let declared = header
            .shape
            .iter()
            .try_fold(1usize, |n, &d| n.checked_mul(d));
        if declared.is_none_or(|n| n > bytes.len()) {
            return Err(self.error(
                name,
                Reason::Invalid(format!(
                    "the .npy header declares shape {} but the member holds only {} bytes",
                    shape_str(&header.shape),
                    bytes.len()
                )),
            ));
        }
        match ArrayD::<T>::read_npy(bytes.as_slice()) {
            Ok(a) => Ok(Ok(a)),
            Err(ReadNpyError::WrongDescriptor(d)) => Ok(Err(dtype_str(d.to_string()))),
            Err(e) => {
                let shape = shape_str(&header.shape);
                let why = match e {
                    ReadNpyError::MissingData => {
                        format!(
                            "the member ends before the data of shape {shape} its header declares"
                        )
                    }
                    ReadNpyError::ExtraBytes(n) => {
                        format!("{n} bytes follow the data of shape {shape} its header declares")
                    }
                    e => format!("cannot read: {e}"),
                };
                Err(self.error(name, Reason::Invalid(why)))
            }
        }
    }

    /// Reads member `name`, which must have dtype `T` (`accepted` names it for the error).
    pub(crate) fn read<T: ReadableElement>(
        &mut self,
        name: &str,
        accepted: &'static str,
    ) -> Result<ArrayD<T>, RayFileError> {
        self.try_read::<T>(name)?
            .map_err(|descr| self.error(name, Reason::Dtype { descr, accepted }))
    }

    /// Reads member `name` as float32, converting float64.
    pub(crate) fn read_float(&mut self, name: &str) -> Result<ArrayD<f32>, RayFileError> {
        if let Ok(a) = self.try_read::<f32>(name)? {
            return Ok(a);
        }
        let a: ArrayD<f64> = self.read(name, "float32, float64")?;
        Ok(a.mapv(|x| x as f32))
    }

    /// Checks that `a` has shape `(N,)` (`cols` is `None`) or `(N, cols)` and returns its elements
    /// in row-major order with `N`.
    pub(crate) fn rows<T: Clone>(
        &self,
        name: &str,
        a: ArrayD<T>,
        cols: Option<usize>,
    ) -> Result<(Vec<T>, usize), RayFileError> {
        let ok = match (a.shape(), cols) {
            ([_], None) => true,
            ([_, c], Some(cols)) => *c == cols,
            _ => false,
        };
        if !ok {
            let expected = match cols {
                None => "(N,)".to_owned(),
                Some(c) => format!("(N, {c})"),
            };
            return Err(self.error(
                name,
                Reason::Shape {
                    shape: a.shape().to_vec(),
                    expected,
                },
            ));
        }
        let n = a.shape()[0];
        Ok((into_row_major(a), n))
    }

    /// Checks that member `name` has `len` rows, like member `other` with `other_len`.
    pub(crate) fn same_length(
        &self,
        name: &str,
        len: usize,
        other: &str,
        other_len: usize,
    ) -> Result<(), RayFileError> {
        if len == other_len {
            Ok(())
        } else {
            Err(self.error(
                name,
                Reason::Length {
                    len,
                    other: other.to_owned(),
                    other_len,
                },
            ))
        }
    }

    /// An error about the values of member `name`.
    pub(crate) fn invalid(&self, name: &str, why: String) -> RayFileError {
        self.error(name, Reason::Invalid(why))
    }
}

/// The elements of `a` in row-major (C) order, without a copy when it already is.
fn into_row_major<T: Clone>(a: ArrayD<T>) -> Vec<T> {
    if !a.is_standard_layout() {
        return a.iter().cloned().collect();
    }
    let len = a.len();
    let (mut v, offset) = a.into_raw_vec_and_offset();
    let start = offset.unwrap_or(0);
    v.truncate(start + len);
    v.drain(..start);
    v
}

/// Reads a float member of shape `(N,)` or `(N, 3)`.
fn read_rows(
    npz: &mut Archive,
    name: &str,
    cols: Option<usize>,
) -> Result<(Vec<f32>, usize), RayFileError> {
    let a = npz.read_float(name)?;
    npz.rows(name, a, cols)
}

/// Reads the rays of a ray file (see `docs/RAYS.md`).
///
/// Members: `origins` (N, 3); `directions` (N, 3), or `dirs` where `directions` is absent;
/// optionally `tmin` and `tmax` (N,), which default to 0 and +inf. Each may be float32 or float64
/// (converted to float32), C or Fortran order, in a compressed or uncompressed archive, with or
/// without the `.npy` suffix on member names. NaN and infinite values are kept: such rays miss.
///
/// Errors name the file, the member and the reason: a missing file or member, an archive that is
/// not a zip, a wrong shape, a row count that differs between members, or another dtype.
pub fn read_rays(path: &Path) -> Result<Vec<Ray>, RayFileError> {
    rays_of(Archive::open(path)?)
}

/// Reads the rays of a ray file held by `reader` (bytes in memory, a stream), as
/// [`read_rays`] does; `name` stands for the file in error messages.
pub fn read_rays_from(
    name: &Path,
    reader: impl Read + Seek + 'static,
) -> Result<Vec<Ray>, RayFileError> {
    rays_of(Archive::from_reader(name, reader)?)
}

/// The member holding the directions: `directions`, else its alias `dirs`.
pub(crate) fn directions_name(npz: &Archive) -> Result<&'static str, RayFileError> {
    match (npz.has("directions"), npz.has("dirs")) {
        (true, _) => Ok("directions"),
        (false, true) => Ok("dirs"),
        (false, false) => Err(npz.error(
            "directions",
            Reason::Missing {
                alias: Some("dirs"),
                present: npz.names.clone(),
            },
        )),
    }
}

fn rays_of(mut npz: Archive) -> Result<Vec<Ray>, RayFileError> {
    let (origins, n) = read_rows(&mut npz, "origins", Some(3))?;
    let dir_name = directions_name(&npz)?;
    let (directions, nd) = read_rows(&mut npz, dir_name, Some(3))?;
    npz.same_length(dir_name, nd, "origins", n)?;
    let mut bound = |name: &str| -> Result<Option<Vec<f32>>, RayFileError> {
        if !npz.has(name) {
            return Ok(None);
        }
        let (v, len) = read_rows(&mut npz, name, None)?;
        npz.same_length(name, len, "origins", n)?;
        Ok(Some(v))
    };
    let tmin = bound("tmin")?;
    let tmax = bound("tmax")?;

    let rays = origins
        .chunks_exact(3)
        .zip(directions.chunks_exact(3))
        .enumerate()
        .map(|(i, (o, d))| Ray {
            origin: Vec3::from_slice(o),
            direction: Vec3::from_slice(d),
            tmin: tmin.as_ref().map_or(0.0, |t| t[i]),
            tmax: tmax.as_ref().map_or(f32::INFINITY, |t| t[i]),
        })
        .collect();
    Ok(rays)
}

/// Writes `rays` as a ray file (`origins`, `directions`, `tmin`, `tmax`, all float32),
/// atomically: the file at `path` is replaced whole or not at all, and only as `replace` says.
pub fn write_rays(path: &Path, rays: &[Ray], replace: hbv::atomic_file::Replace) -> io::Result<()> {
    use ndarray::{Array1, Array2};
    let rows = |f: fn(&Ray) -> Vec3| -> Array2<f32> {
        let flat: Vec<f32> = rays.iter().flat_map(|r| f(r).to_array()).collect();
        Array2::from_shape_vec((rays.len(), 3), flat).expect("3 values per ray")
    };
    let origins = rows(|r| r.origin);
    let directions = rows(|r| r.direction);
    let tmin: Array1<f32> = rays.iter().map(|r| r.tmin).collect();
    let tmax: Array1<f32> = rays.iter().map(|r| r.tmax).collect();
    hbv::atomic_file::write_atomically(path, replace, |file| {
        let mut npz = NpzStream::new(file);
        npz.add("origins", &origins)?;
        npz.add("directions", &directions)?;
        npz.add("tmin", &tmin)?;
        npz.add("tmax", &tmax)?;
        npz.finish()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_member_is_read_only_up_to_its_declared_size() {
        let data = [7u8; 100];
        let mut bytes = Vec::new();
        read_declared(100, &data[..], &mut bytes).unwrap();
        assert_eq!(bytes.len(), 100);
        let mut bytes = Vec::new();
        let problem = read_declared(99, &data[..], &mut bytes).unwrap_err();
        assert!(
            matches!(problem, MemberProblem::LongerThanDeclared(99)),
            "{problem}"
        );
        assert!(bytes.len() <= 100);
    }

    #[test]
    fn a_declared_size_beyond_memory_is_refused_before_reading() {
        // A reader that must never be read: the size is refused first.
        struct Untouchable;
        impl Read for Untouchable {
            fn read(&mut self, _: &mut [u8]) -> io::Result<usize> {
                panic!("read before the declared size was checked")
            }
        }
        let mut bytes = Vec::new();
        let problem = read_declared(u64::MAX / 2, Untouchable, &mut bytes).unwrap_err();
        assert!(matches!(problem, MemberProblem::TooLarge(_)), "{problem}");
        assert!(problem
            .to_string()
            .contains("more than this machine can hold"));
    }
}
