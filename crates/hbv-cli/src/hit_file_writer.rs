//! Writing hit and occlusion files (`docs/RAYS.md`) a chunk of rays at a time, into an archive
//! laid out for all of them up front (`NpzInPlace`): memory for one chunk's columns, whatever
//! the number of rays.

use std::fs::File;
use std::io::{self, Cursor, Seek, Write};

use hbv::scene::SceneHit;

use crate::npz_in_place::{MemberSpec, NpzInPlace, WriteSeek};

/// Which file is written: closest hits, or any-hit answers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HitFileKind {
    /// Members `hit`, `t`, `prim`, `u`, `v`, `instance`, `normal`.
    Closest,
    /// Member `occluded`.
    Occlusion,
}

impl HitFileKind {
    /// The members of a file of this kind for `rays` rays, in the order they are stored.
    fn members(self, rays: usize) -> Vec<MemberSpec> {
        match self {
            HitFileKind::Closest => vec![
                MemberSpec::new::<bool>("hit", &[rays]),
                MemberSpec::new::<f32>("t", &[rays]),
                MemberSpec::new::<i64>("prim", &[rays]),
                MemberSpec::new::<f32>("u", &[rays]),
                MemberSpec::new::<f32>("v", &[rays]),
                MemberSpec::new::<i64>("instance", &[rays]),
                MemberSpec::new::<f32>("normal", &[rays, 3]),
            ],
            HitFileKind::Occlusion => vec![MemberSpec::new::<bool>("occluded", &[rays])],
        }
    }
}

/// A hit or occlusion file being written, the answers of consecutive rays at a time.
pub struct HitFileWriter<'a> {
    npz: NpzInPlace<&'a mut dyn WriteSeek>,
    kind: HitFileKind,
    rays: usize,
    written: usize,
    /// One member's bytes for the current chunk, reused.
    bytes: Vec<u8>,
}

impl HitFileWriter<'_> {
    /// Writes the closest hits of the next `hits.len()` rays: `hit` (bool), `t` (float32, +inf
    /// on a miss), `prim` and `instance` (int64, -1 on a miss), `u`, `v` (float32, 0 on a
    /// miss) and `normal` (float32 × 3, 0 on a miss).
    ///
    /// # Panics
    /// On an occlusion file, or past the number of rays the file was laid out for.
    pub fn write_hits(&mut self, hits: &[Option<SceneHit>]) -> io::Result<()> {
        assert_eq!(
            self.kind,
            HitFileKind::Closest,
            "hits into an occlusion file"
        );
        self.advance(hits.len());
        let t = |h: &SceneHit| h.t.to_le_bytes();
        let u = |h: &SceneHit| h.u.to_le_bytes();
        let v = |h: &SceneHit| h.v.to_le_bytes();
        let prim = |h: &SceneHit| i64::from(h.prim).to_le_bytes();
        let instance = |h: &SceneHit| i64::from(h.instance).to_le_bytes();
        let normal = |h: &SceneHit| {
            let mut bytes = [0u8; 12];
            for (axis, chunk) in bytes.chunks_exact_mut(4).enumerate() {
                chunk.copy_from_slice(&h.normal[axis].to_le_bytes());
            }
            bytes
        };
        self.column(0, hits, |h| [u8::from(h.is_some())])?;
        self.column(1, hits, |h| {
            h.as_ref().map_or(f32::INFINITY.to_le_bytes(), t)
        })?;
        self.column(2, hits, |h| h.as_ref().map_or((-1i64).to_le_bytes(), prim))?;
        self.column(3, hits, |h| h.as_ref().map_or([0; 4], u))?;
        self.column(4, hits, |h| h.as_ref().map_or([0; 4], v))?;
        self.column(5, hits, |h| {
            h.as_ref().map_or((-1i64).to_le_bytes(), instance)
        })?;
        self.column(6, hits, |h| h.as_ref().map_or([0; 12], normal))
    }

    /// Writes the any-hit answers of the next `occluded.len()` rays.
    ///
    /// # Panics
    /// On a closest-hit file, or past the number of rays the file was laid out for.
    pub fn write_occluded(&mut self, occluded: &[bool]) -> io::Result<()> {
        assert_eq!(
            self.kind,
            HitFileKind::Occlusion,
            "occlusion into a hit file"
        );
        self.advance(occluded.len());
        self.column(0, occluded, |&o| [u8::from(o)])
    }

    fn advance(&mut self, rays: usize) {
        self.written += rays;
        assert!(self.written <= self.rays, "more answers than rays");
    }

    /// Appends `encode` of each item to member `index`.
    fn column<T, const N: usize>(
        &mut self,
        index: usize,
        items: &[T],
        encode: impl Fn(&T) -> [u8; N],
    ) -> io::Result<()> {
        self.bytes.clear();
        self.bytes.extend(items.iter().flat_map(encode));
        self.npz.append(index, &self.bytes)
    }
}

/// Writes a `kind` file for `rays` rays into `file` (from its start), each ray's answers
/// handed over by `fill` in ray order, a chunk at a time.
///
/// A file that can seek is written in place, with memory for one chunk; one that cannot (a
/// named pipe) gets the archive built in memory and then written in one go.
///
/// # Panics
/// If `fill` returns `Ok` without having written every ray's answers: a bug of the caller.
pub fn write_hit_file(
    file: &mut File,
    kind: HitFileKind,
    rays: usize,
    fill: impl FnOnce(&mut HitFileWriter) -> io::Result<()>,
) -> io::Result<()> {
    if file.stream_position().is_ok() {
        fill_archive(file, kind, rays, fill)
    } else {
        let mut memory = Cursor::new(Vec::new());
        fill_archive(&mut memory, kind, rays, fill)?;
        file.write_all(memory.get_ref())?;
        file.flush()
    }
}

fn fill_archive(
    out: &mut dyn WriteSeek,
    kind: HitFileKind,
    rays: usize,
    fill: impl FnOnce(&mut HitFileWriter) -> io::Result<()>,
) -> io::Result<()> {
    let mut writer = HitFileWriter {
        npz: NpzInPlace::new(out, kind.members(rays))?,
        kind,
        rays,
        written: 0,
        bytes: Vec::new(),
    };
    fill(&mut writer)?;
    assert_eq!(writer.written, rays, "answers for every ray");
    writer.npz.finish()?;
    Ok(())
}
