//! Writing an uncompressed `.npz` archive whose members' sizes are known before their contents:
//! the archive is laid out once, each member is filled in order by position (members in any
//! interleaving), and the checksums and the central directory are written at the end.
//!
//! A hit file of N rays has members of known dtypes and shapes, so its layout is fixed before
//! the first ray is traced: `hbv trace` writes each chunk's answers straight into their places
//! in every member, with memory for one chunk, where a member-after-member writer
//! ([`crate::npz_writer::NpzStream`]) needs every answer before it can write the first member.
//!
//! Layout (PKWARE APPNOTE 6.3.x): per member a local file header, the `.npy` header, the data;
//! then the central directory and the end record. Sizes are written in the local headers (no
//! data descriptors), the CRC-32 of each member is patched into its local header when the
//! member is complete. Zip64 fields are used where a size or an offset reaches 4 GiB
//! (0xFFFF_FFFF), so that members of more than 4 GiB and archives of any size are read by
//! NumPy and the zip crate.

use std::io::{self, Seek, SeekFrom, Write};

use ndarray_npy::npy::header::{Header, Layout};
use ndarray_npy::WritableElement;

/// Anything an archive is written into by position: a file, or bytes in memory.
pub trait WriteSeek: Write + Seek {}
impl<T: Write + Seek> WriteSeek for T {}

/// One member of an archive to lay out: `NAME.npy` holding an array of element type `T`.
#[derive(Clone, Debug)]
pub struct MemberSpec {
    name: String,
    header: Vec<u8>,
    element_size: u64,
    elements: u64,
}

impl MemberSpec {
    /// An array of element type `T` and `shape`, in C order, stored as `name.npy`.
    pub fn new<T: WritableElement>(name: &str, shape: &[usize]) -> Self {
        let header = Header {
            type_descriptor: T::type_descriptor(),
            layout: Layout::Standard,
            shape: shape.to_vec(),
        }
        .to_bytes()
        .expect("a header of one dtype and a short shape fits a .npy header");
        Self {
            name: format!("{name}.npy"),
            header,
            element_size: std::mem::size_of::<T>() as u64,
            elements: shape.iter().map(|&d| d as u64).product(),
        }
    }

    fn data_len(&self) -> u64 {
        self.element_size * self.elements
    }

    /// The member's uncompressed (and stored) size: its `.npy` header and data.
    fn size(&self) -> u64 {
        self.header.len() as u64 + self.data_len()
    }
}

/// Sizes and offsets from this value on are written as zip64 fields.
const ZIP64_FROM: u64 = 0xFFFF_FFFF;

/// Signatures of the zip records (APPNOTE 4.3.7, 4.3.12, 4.3.14, 4.3.15, 4.3.16).
const LOCAL_HEADER: u32 = 0x0403_4b50;
const CENTRAL_HEADER: u32 = 0x0201_4b50;
const ZIP64_END: u32 = 0x0606_4b50;
const ZIP64_LOCATOR: u32 = 0x0706_4b50;
const END: u32 = 0x0605_4b50;
/// Header id of the zip64 extended information extra field.
const ZIP64_EXTRA: u16 = 0x0001;
/// 1980-01-01 00:00 in MS-DOS date format: a fixed time, so that equal answers give equal files.
const DOS_DATE: u16 = (1 << 5) | 1;

/// Where a member lies in the archive and how far it is filled.
struct Placed {
    spec: MemberSpec,
    /// Offset of its local file header.
    header_offset: u64,
    /// Offset of its first data byte (after the `.npy` header).
    data_offset: u64,
    /// Whether its local header carries zip64 sizes.
    zip64_sizes: bool,
    written: u64,
    crc: crc32fast::Hasher,
}

/// An uncompressed `.npz` archive being filled in place (see the [module](self)).
pub struct NpzInPlace<W: WriteSeek> {
    out: W,
    members: Vec<Placed>,
    /// Offset just past the last member: the central directory's.
    end: u64,
    zip64_from: u64,
}

impl<W: WriteSeek> NpzInPlace<W> {
    /// Lays out `members` in `out` (from its start) and writes their local and `.npy` headers.
    pub fn new(out: W, members: Vec<MemberSpec>) -> io::Result<Self> {
        Self::with_zip64_from(out, members, ZIP64_FROM)
    }

    /// As [`NpzInPlace::new`], with zip64 fields from `zip64_from` on (0: everywhere), so that
    /// tests can read zip64 archives without writing 4 GiB.
    pub fn with_zip64_from(
        mut out: W,
        members: Vec<MemberSpec>,
        zip64_from: u64,
    ) -> io::Result<Self> {
        let mut at = 0u64;
        let mut placed = Vec::with_capacity(members.len());
        for spec in members {
            let zip64_sizes = spec.size() >= zip64_from;
            let mut local = Vec::new();
            local_header(&mut local, &spec, 0, zip64_sizes);
            local.extend_from_slice(&spec.header);
            out.seek(SeekFrom::Start(at))?;
            out.write_all(&local)?;
            let mut crc = crc32fast::Hasher::new();
            crc.update(&spec.header);
            let data_offset = at + local.len() as u64;
            placed.push(Placed {
                header_offset: at,
                data_offset,
                zip64_sizes,
                written: 0,
                crc,
                spec,
            });
            at = data_offset + placed.last().expect("just pushed").spec.data_len();
        }
        Ok(Self {
            out,
            members: placed,
            end: at,
            zip64_from,
        })
    }

    /// Appends `bytes` to the data of member `index` (in the order of [`NpzInPlace::new`]).
    ///
    /// # Panics
    /// If the member would hold more bytes than its shape declares: a bug of the caller.
    pub fn append(&mut self, index: usize, bytes: &[u8]) -> io::Result<()> {
        let member = &mut self.members[index];
        let len = bytes.len() as u64;
        assert!(
            member.written + len <= member.spec.data_len(),
            "{}: more data than its shape declares",
            member.spec.name
        );
        self.out
            .seek(SeekFrom::Start(member.data_offset + member.written))?;
        self.out.write_all(bytes)?;
        member.crc.update(bytes);
        member.written += len;
        Ok(())
    }

    /// Patches each member's CRC-32 into its local header, writes the central directory and the
    /// end records, flushes, and returns the output.
    ///
    /// # Panics
    /// If a member holds fewer bytes than its shape declares: a bug of the caller.
    pub fn finish(mut self) -> io::Result<W> {
        let mut directory = Vec::new();
        for member in &self.members {
            assert_eq!(
                member.written,
                member.spec.data_len(),
                "{}: less data than its shape declares",
                member.spec.name
            );
            let crc = member.crc.clone().finalize();
            // The CRC-32 field is at byte 14 of a local file header.
            self.out.seek(SeekFrom::Start(member.header_offset + 14))?;
            self.out.write_all(&crc.to_le_bytes())?;
            central_header(&mut directory, member, crc, self.zip64_from);
        }
        let count = self.members.len() as u64;
        let directory_len = directory.len() as u64;
        let zip64_end = self.end;
        let zip64 = count >= 0xFFFF
            || [zip64_end, directory_len]
                .iter()
                .any(|&x| x >= self.zip64_from);
        if zip64 {
            let zip64_end_offset = self.end + directory_len;
            // Zip64 end of central directory record (APPNOTE 4.3.14), version 1, no extensible data.
            put32(&mut directory, ZIP64_END);
            put64(&mut directory, 44);
            put16(&mut directory, 45);
            put16(&mut directory, 45);
            put32(&mut directory, 0);
            put32(&mut directory, 0);
            put64(&mut directory, count);
            put64(&mut directory, count);
            put64(&mut directory, directory_len);
            put64(&mut directory, self.end);
            // Zip64 end of central directory locator (4.3.15).
            put32(&mut directory, ZIP64_LOCATOR);
            put32(&mut directory, 0);
            put64(&mut directory, zip64_end_offset);
            put32(&mut directory, 1);
        }
        // End of central directory record (4.3.16): fields that overflow say 0xFFFF.. and are
        // read from the zip64 record.
        put32(&mut directory, END);
        put16(&mut directory, 0);
        put16(&mut directory, 0);
        let short_count = if zip64 { 0xFFFF } else { count as u16 };
        put16(&mut directory, short_count);
        put16(&mut directory, short_count);
        put32(&mut directory, clamp32(directory_len, zip64));
        put32(&mut directory, clamp32(self.end, zip64));
        put16(&mut directory, 0);
        self.out.seek(SeekFrom::Start(self.end))?;
        self.out.write_all(&directory)?;
        self.out.flush()?;
        Ok(self.out)
    }
}

/// A local file header (APPNOTE 4.3.7) for `spec`, stored, with `crc` and, where
/// `zip64_sizes`, the sizes in a zip64 extra field (4.5.3).
fn local_header(out: &mut Vec<u8>, spec: &MemberSpec, crc: u32, zip64_sizes: bool) {
    let size = spec.size();
    put32(out, LOCAL_HEADER);
    put16(out, if zip64_sizes { 45 } else { 20 });
    put16(out, 0); // flags
    put16(out, 0); // stored
    put16(out, 0); // time
    put16(out, DOS_DATE);
    put32(out, crc);
    put32(out, clamp32(size, zip64_sizes));
    put32(out, clamp32(size, zip64_sizes));
    put16(out, spec.name.len() as u16);
    put16(out, if zip64_sizes { 20 } else { 0 });
    out.extend_from_slice(spec.name.as_bytes());
    if zip64_sizes {
        put16(out, ZIP64_EXTRA);
        put16(out, 16);
        put64(out, size);
        put64(out, size);
    }
}

/// The central directory header (APPNOTE 4.3.12) of `member`; the zip64 extra field holds, in
/// order, the sizes and the offset whose 32-bit fields say 0xFFFF_FFFF (4.5.3).
fn central_header(out: &mut Vec<u8>, member: &Placed, crc: u32, zip64_from: u64) {
    let size = member.spec.size();
    let big_size = size >= zip64_from;
    let big_offset = member.header_offset >= zip64_from;
    let mut extra = Vec::new();
    if big_size {
        put64(&mut extra, size);
        put64(&mut extra, size);
    }
    if big_offset {
        put64(&mut extra, member.header_offset);
    }
    let zip64 = !extra.is_empty();
    put32(out, CENTRAL_HEADER);
    put16(out, 45); // made by: version 4.5
    put16(out, if zip64 || member.zip64_sizes { 45 } else { 20 });
    put16(out, 0);
    put16(out, 0);
    put16(out, 0);
    put16(out, DOS_DATE);
    put32(out, crc);
    put32(out, clamp32(size, big_size));
    put32(out, clamp32(size, big_size));
    put16(out, member.spec.name.len() as u16);
    put16(out, if zip64 { extra.len() as u16 + 4 } else { 0 });
    put16(out, 0); // comment
    put16(out, 0); // disk
    put16(out, 0); // internal attributes
    put32(out, 0); // external attributes
    put32(out, clamp32(member.header_offset, big_offset));
    out.extend_from_slice(member.spec.name.as_bytes());
    if zip64 {
        put16(out, ZIP64_EXTRA);
        put16(out, extra.len() as u16);
        out.extend_from_slice(&extra);
    }
}

/// `value` as a 32-bit field: 0xFFFF_FFFF where it is kept in a zip64 field instead.
fn clamp32(value: u64, zip64: bool) -> u32 {
    if zip64 {
        0xFFFF_FFFF
    } else {
        value as u32
    }
}

fn put16(out: &mut Vec<u8>, value: u16) {
    out.extend_from_slice(&value.to_le_bytes());
}

fn put32(out: &mut Vec<u8>, value: u32) {
    out.extend_from_slice(&value.to_le_bytes());
}

fn put64(out: &mut Vec<u8>, value: u64) {
    out.extend_from_slice(&value.to_le_bytes());
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::{Array1, Array2};
    use ndarray_npy::NpzReader;
    use std::io::Cursor;

    /// An archive of `t` (float32, (5,)) and `normal` (float32, (5, 3)) filled in two chunks,
    /// interleaved, with zip64 fields from `zip64_from` on.
    fn archive(zip64_from: u64) -> Vec<u8> {
        let members = vec![
            MemberSpec::new::<f32>("t", &[5]),
            MemberSpec::new::<f32>("normal", &[5, 3]),
        ];
        let mut npz =
            NpzInPlace::with_zip64_from(Cursor::new(Vec::new()), members, zip64_from).unwrap();
        let bytes = |v: &[f32]| -> Vec<u8> { v.iter().flat_map(|x| x.to_le_bytes()).collect() };
        npz.append(1, &bytes(&[0.0, 1.0, 2.0, 3.0, 4.0, 5.0]))
            .unwrap();
        npz.append(0, &bytes(&[10.0, 11.0])).unwrap();
        npz.append(0, &bytes(&[12.0, 13.0, 14.0])).unwrap();
        npz.append(
            1,
            &bytes(&[6.0, 7.0, 8.0, 9.0, 10.0, 11.0, 12.0, 13.0, 14.0]),
        )
        .unwrap();
        npz.finish().unwrap().into_inner()
    }

    #[test]
    fn members_filled_in_any_interleaving_read_back_with_checksums() {
        for zip64_from in [ZIP64_FROM, 0] {
            let bytes = archive(zip64_from);
            let mut npz = NpzReader::new(Cursor::new(bytes)).unwrap();
            assert_eq!(npz.names().unwrap(), ["t", "normal"]);
            let t: Array1<f32> = npz.by_name("t").unwrap();
            assert_eq!(t, Array1::from(vec![10.0, 11.0, 12.0, 13.0, 14.0]));
            let normal: Array2<f32> = npz.by_name("normal").unwrap();
            assert_eq!(
                normal,
                Array2::from_shape_fn((5, 3), |(i, j)| (3 * i + j) as f32)
            );
        }
    }

    #[test]
    fn zip64_is_used_only_where_asked() {
        let plain = archive(ZIP64_FROM);
        let wide = archive(0);
        assert!(!plain.windows(4).any(|w| w == ZIP64_END.to_le_bytes()));
        assert!(wide.windows(4).any(|w| w == ZIP64_END.to_le_bytes()));
        // The zip crate checks the CRC-32 of every member it reads to the end.
        for bytes in [plain, wide] {
            let mut zip = zip::ZipArchive::new(Cursor::new(bytes)).unwrap();
            for i in 0..zip.len() {
                let mut member = zip.by_index(i).unwrap();
                io::copy(&mut member, &mut io::sink()).unwrap();
            }
        }
    }

    #[test]
    fn a_damaged_member_fails_its_checksum() {
        let mut bytes = archive(ZIP64_FROM);
        let last = {
            let mut zip = zip::ZipArchive::new(Cursor::new(bytes.clone())).unwrap();
            let member = zip.by_name("t.npy").unwrap();
            (member.data_start() + member.size() - 1) as usize
        };
        bytes[last] ^= 1;
        let mut zip = zip::ZipArchive::new(Cursor::new(bytes)).unwrap();
        let mut member = zip.by_name("t.npy").unwrap();
        assert!(io::copy(&mut member, &mut io::sink()).is_err());
    }
}
