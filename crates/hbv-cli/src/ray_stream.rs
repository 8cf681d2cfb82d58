//! Reading a ray file (`docs/RAYS.md`) a chunk of rays at a time, with memory for one chunk
//! whatever the size of the file.
//!
//! Each member is read from its own handle on the file, in ray order: a stored member (what
//! `numpy.savez` writes) from its place in the archive, a deflated one
//! (`numpy.savez_compressed`) through a decoder as it goes, so that no member is ever held
//! whole. A member in Fortran order ((N, 3) stored component by component) is read as three
//! streams, one per component. The members, dtypes and shapes accepted, and the messages of a
//! bad file, are those of [`crate::ray_file::read_rays`]; the CRC-32 of a member in C order is
//! checked once its last row is read, so a damaged member fails the run that reads it.

use std::fs::File;
use std::io::{self, BufReader, Read, Seek, SeekFrom};
use std::path::Path;

use flate2::read::DeflateDecoder;
use glam::Vec3;
use hbv::geometry::Ray;

use crate::npy_header::read_npy_header;
use crate::ray_file::{
    directions_name, dtype_str, shape_str, Archive, MemberPlace, RayFileError, Reason,
};

/// A ray file open for reading in chunks (see the [module](self)).
pub struct RayChunks {
    len: usize,
    next: usize,
    origins: Column,
    directions: Column,
    tmin: Option<Column>,
    tmax: Option<Column>,
    /// Each member's values for the current chunk, reused.
    values: [Vec<f32>; 4],
}

impl RayChunks {
    /// Opens the ray file at `path` and checks its members' headers, dtypes, shapes and sizes
    /// (the data is read by [`RayChunks::read_next`]).
    pub fn open(path: &Path) -> Result<Self, RayFileError> {
        let mut npz = Archive::open(path)?;
        let origins = Column::open(&mut npz, "origins", Some(3))?;
        let dir_name = directions_name(&npz)?;
        let directions = Column::open(&mut npz, dir_name, Some(3))?;
        npz.same_length(dir_name, directions.rows, "origins", origins.rows)?;
        let mut bound = |name: &str| -> Result<Option<Column>, RayFileError> {
            if !npz.has(name) {
                return Ok(None);
            }
            let column = Column::open(&mut npz, name, None)?;
            npz.same_length(name, column.rows, "origins", origins.rows)?;
            Ok(Some(column))
        };
        let tmin = bound("tmin")?;
        let tmax = bound("tmax")?;
        Ok(Self {
            len: origins.rows,
            next: 0,
            origins,
            directions,
            tmin,
            tmax,
            values: Default::default(),
        })
    }

    /// The number of rays in the file.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether the file holds no rays.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Rays not read yet.
    pub fn remaining(&self) -> usize {
        self.len - self.next
    }

    /// Reads the next `max` rays (fewer at the end of the file) into `rays`, which is cleared
    /// first; returns how many were read, 0 at the end.
    ///
    /// An error names the file, the member and the rows: the file ends or cannot be read
    /// within them, a deflated member does not decode, or a member's CRC-32 differs from
    /// the archive's.
    pub fn read_next(&mut self, max: usize, rays: &mut Vec<Ray>) -> Result<usize, RayFileError> {
        rays.clear();
        let count = max.min(self.remaining());
        let rows = self.next..self.next + count;
        let [origins, directions, tmin, tmax] = &mut self.values;
        self.origins.read(rows.clone(), origins)?;
        self.directions.read(rows.clone(), directions)?;
        for (column, values) in [(&mut self.tmin, &mut *tmin), (&mut self.tmax, &mut *tmax)] {
            if let Some(column) = column {
                column.read(rows.clone(), values)?;
            }
        }
        rays.extend((0..count).map(|i| Ray {
            origin: Vec3::from_slice(&origins[3 * i..3 * i + 3]),
            direction: Vec3::from_slice(&directions[3 * i..3 * i + 3]),
            tmin: self.tmin.as_ref().map_or(0.0, |_| tmin[i]),
            tmax: self.tmax.as_ref().map_or(f32::INFINITY, |_| tmax[i]),
        }));
        self.next = rows.end;
        Ok(count)
    }
}

/// How a member's elements are stored.
#[derive(Clone, Copy)]
struct Element {
    /// 4 (float32) or 8 (float64).
    size: usize,
    big_endian: bool,
}

impl Element {
    /// The element type of a `.npy` dtype descriptor (`'<f4'`), if it is a float32 or float64.
    fn of(descr: &str) -> Option<Self> {
        let (big_endian, code) = match descr.trim_matches('\'').split_at_checked(1)? {
            ("<" | "=", code) => (false, code),
            (">", code) => (true, code),
            _ => return None,
        };
        let size = match code {
            "f4" => 4,
            "f8" => 8,
            _ => return None,
        };
        Some(Self { size, big_endian })
    }

    /// Appends the elements of `bytes` to `out`, as float32 (float64 rounded).
    fn decode(self, bytes: &[u8], out: &mut Vec<f32>) {
        match (self.size, self.big_endian) {
            (4, false) => out.extend(
                bytes
                    .chunks_exact(4)
                    .map(|b| f32::from_le_bytes(b.try_into().unwrap())),
            ),
            (4, true) => out.extend(
                bytes
                    .chunks_exact(4)
                    .map(|b| f32::from_be_bytes(b.try_into().unwrap())),
            ),
            (_, false) => out.extend(
                bytes
                    .chunks_exact(8)
                    .map(|b| f64::from_le_bytes(b.try_into().unwrap()) as f32),
            ),
            (_, true) => out.extend(
                bytes
                    .chunks_exact(8)
                    .map(|b| f64::from_be_bytes(b.try_into().unwrap()) as f32),
            ),
        }
    }
}

/// One member of the ray file, read in row order.
struct Column {
    /// The member as the user names it (without `.npy`), for errors.
    name: String,
    path: std::path::PathBuf,
    rows: usize,
    /// Values per row: 1 for (N,), 3 for (N, 3).
    width: usize,
    element: Element,
    /// One stream of whole rows (C order, or one value per row); else one per component
    /// (Fortran order).
    streams: Vec<MemberStream>,
    bytes: Vec<u8>,
    component: Vec<f32>,
}

impl Column {
    /// Opens member `name` of shape (N,) (`width` is `None`) or (N, `width`) and checks its
    /// header against its size.
    fn open(npz: &mut Archive, name: &str, width: Option<usize>) -> Result<Self, RayFileError> {
        let place = npz.locate(name)?;
        let path = npz.path().to_owned();
        let cannot_read =
            |e: io::Error| npz.error(name, Reason::Invalid(format!("cannot read: {e}")));
        let mut head = MemberStream::open(&path, &place, 0, true).map_err(cannot_read)?;
        let header_bytes = read_header_bytes(&mut head, place.size).map_err(cannot_read)?;
        let invalid = |why: String| npz.error(name, Reason::Invalid(why));
        let header = read_npy_header(&header_bytes).map_err(invalid)?;
        let descr = header.type_descriptor.to_string();
        let element = Element::of(&descr).ok_or_else(|| {
            npz.error(
                name,
                Reason::Dtype {
                    descr: dtype_str(descr.clone()),
                    accepted: "float32, float64",
                },
            )
        })?;
        let (rows, row_width) = match (header.shape.as_slice(), width) {
            (&[n], None) => (n, 1),
            (&[n, c], Some(w)) if c == w => (n, w),
            (shape, _) => {
                let expected = width.map_or("(N,)".to_owned(), |w| format!("(N, {w})"));
                return Err(npz.error(
                    name,
                    Reason::Shape {
                        shape: shape.to_vec(),
                        expected,
                    },
                ));
            }
        };
        let shape = shape_str(&header.shape);
        let held = place.size - header_bytes.len() as u64;
        let declared = (rows as u128) * (row_width as u128) * (element.size as u128);
        // Every element takes at least one byte: a count beyond the member's bytes is a header
        // that lies (the message of the whole-file reader).
        if (rows as u128) * (row_width as u128) > u128::from(place.size) {
            return Err(invalid(format!(
                "the .npy header declares shape {shape} but the member holds only {} bytes",
                place.size
            )));
        }
        if declared > u128::from(held) {
            return Err(invalid(format!(
                "the member ends before the data of shape {shape} its header declares"
            )));
        }
        // A deflated member's declared size bounds it (more data is found by its decoding,
        // [`MemberStream::check_end`]); a stored one's is its size.
        if declared < u128::from(held) && !place.deflated {
            let extra = u128::from(held) - declared;
            return Err(invalid(format!(
                "{extra} bytes follow the data of shape {shape} its header declares"
            )));
        }
        let mut streams = vec![head];
        if header.layout.is_fortran() && row_width > 1 {
            // Component c starts c·N elements into the data; the CRC-32, which needs the member
            // read in its order, is not checked.
            streams[0].crc = None;
            for c in 1..row_width {
                let skip = header_bytes.len() as u64 + (c * rows * element.size) as u64;
                streams.push(MemberStream::open(&path, &place, skip, false).map_err(cannot_read)?);
            }
        }
        Ok(Self {
            name: name.to_owned(),
            path,
            rows,
            width: row_width,
            element,
            streams,
            bytes: Vec::new(),
            component: Vec::new(),
        })
    }

    /// Reads `rows` (the next ones) into `values`, `width` values per row; after the last
    /// row, checks the member's end and CRC-32.
    fn read(
        &mut self,
        rows: std::ops::Range<usize>,
        values: &mut Vec<f32>,
    ) -> Result<(), RayFileError> {
        values.clear();
        let count = rows.len();
        let error =
            |why: String| RayFileError::new(&self.path, Some(&self.name), Reason::Invalid(why));
        let failed = |e: io::Error| {
            let why = if e.kind() == io::ErrorKind::UnexpectedEof {
                "the member ends before them".to_owned()
            } else {
                e.to_string()
            };
            error(format!(
                "cannot read rows {} to {}: {why}",
                rows.start, rows.end
            ))
        };
        if self.streams.len() == 1 {
            self.bytes.resize(count * self.width * self.element.size, 0);
            self.streams[0]
                .read_exact(&mut self.bytes)
                .map_err(failed)?;
            self.element.decode(&self.bytes, values);
        } else {
            values.resize(count * self.width, 0.0);
            for (c, stream) in self.streams.iter_mut().enumerate() {
                self.bytes.resize(count * self.element.size, 0);
                stream.read_exact(&mut self.bytes).map_err(failed)?;
                self.component.clear();
                self.element.decode(&self.bytes, &mut self.component);
                for (row, &value) in self.component.iter().enumerate() {
                    values[row * self.width + c] = value;
                }
            }
        }
        // A stream of whole rows has then read the member to its end (the streams of a member
        // in Fortran order end where the next component starts).
        if rows.end == self.rows && self.streams.len() == 1 {
            self.streams[0].check_end().map_err(error)?;
        }
        Ok(())
    }
}

/// The `.npy` prefix and header at the start of a member of `size` bytes (no more than the
/// member holds, whatever the header declares: [`read_npy_header`] says what is wrong).
fn read_header_bytes(member: &mut MemberStream, size: u64) -> io::Result<Vec<u8>> {
    let mut bytes = Vec::new();
    let mut read_up_to = |bytes: &mut Vec<u8>, len: u64| {
        let want = len.min(size).saturating_sub(bytes.len() as u64);
        member.take(want).read_to_end(bytes)
    };
    read_up_to(&mut bytes, 10)?;
    // Versions 2.0 and 3.0 spell the header length in 4 bytes, 1.0 in 2.
    let prefix = if bytes.get(6) == Some(&1) { 10 } else { 12 };
    read_up_to(&mut bytes, prefix)?;
    if let Some(field) = bytes.get(8..prefix as usize) {
        let declared = field
            .iter()
            .rev()
            .fold(0u64, |n, &b| (n << 8) | u64::from(b));
        read_up_to(&mut bytes, prefix + declared)?;
    }
    Ok(bytes)
}

/// The uncompressed bytes of an archive member, from an offset on, read through a handle of
/// its own; with their CRC-32 where the stream starts at the member's start.
struct MemberStream {
    reader: Box<dyn Read + Send>,
    /// The running CRC-32 and the archive's, where checked.
    crc: Option<(crc32fast::Hasher, u32)>,
}

impl MemberStream {
    /// The bytes of the member at `place` in the file at `path`, from `offset` on (decoded up
    /// to there for a deflated member); `check_crc` for a stream read whole from offset 0.
    fn open(path: &Path, place: &MemberPlace, offset: u64, check_crc: bool) -> io::Result<Self> {
        let mut file = File::open(path)?;
        let reader: Box<dyn Read + Send> = if place.deflated {
            file.seek(SeekFrom::Start(place.data_start))?;
            let mut decoder = DeflateDecoder::new(BufReader::new(file.take(place.stored_size)));
            io::copy(&mut (&mut decoder).take(offset), &mut io::sink())?;
            Box::new(decoder)
        } else {
            file.seek(SeekFrom::Start(place.data_start + offset))?;
            Box::new(file.take(place.stored_size.saturating_sub(offset)))
        };
        Ok(Self {
            reader,
            crc: check_crc.then(|| (crc32fast::Hasher::new(), place.crc32)),
        })
    }

    /// Checks, after the member's declared data, that it ends there and matches its CRC-32.
    fn check_end(&mut self) -> Result<(), String> {
        let mut extra = [0u8; 1];
        match self.read(&mut extra) {
            Ok(0) => {}
            Ok(_) => return Err("more bytes follow the data its header declares".into()),
            Err(e) => return Err(format!("cannot read its end: {e}")),
        }
        match &self.crc {
            Some((hasher, expected)) if hasher.clone().finalize() != *expected => Err(
                "its bytes do not match the archive's CRC-32 checksum (the file is damaged)".into(),
            ),
            _ => Ok(()),
        }
    }
}

impl Read for MemberStream {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let n = self.reader.read(buf)?;
        if let Some((hasher, _)) = &mut self.crc {
            hasher.update(&buf[..n]);
        }
        Ok(n)
    }
}
