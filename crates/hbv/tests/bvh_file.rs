//! `.hbv` files: what is saved loads back the same, and every kind of bad file gives its own
//! clear error naming the file (never a panic, never a huge allocation).

mod common;

use std::path::Path;

use common::{assert_agrees, mesh_and_rays, soup};
use hbv::bvh::build::{BinnedSahBuilder, Builder, InsertionBuilder};
use hbv::bvh::file::{is_bvh_file, BvhFile, BvhFileError, FORMAT_VERSION, MAGIC};
use hbv::bvh::layout::RecursiveLayout;
use hbv::bvh::optimize::ReinsertionOptimizer;
use hbv::bvh::BuildTree;
use hbv::glam::Vec3;
use hbv::mesh::procedural::{icosphere, torus};
use proptest::prelude::*;

const SOURCE: &str = "scene.hbv";

fn saved(mesh: &hbv::TriangleMesh, tree: BuildTree) -> BvhFile {
    BvhFile {
        mesh: mesh.clone(),
        tree,
        settings: "binned-sah (leaf size 4) + reinsertion optimization".into(),
    }
}

fn sample() -> BvhFile {
    let mesh = torus(Vec3::ZERO, 2.0, 0.5, 12, 6);
    let tree = BinnedSahBuilder::default().build(&mesh);
    saved(&mesh, tree)
}

fn load(bytes: &[u8]) -> Result<BvhFile, BvhFileError> {
    BvhFile::from_bytes(bytes, Path::new(SOURCE))
}

/// Loading `bytes` fails with a message naming the file and containing `want`.
fn assert_fails(bytes: &[u8], want: &str) {
    let err = load(bytes).expect_err(want).to_string();
    assert!(err.starts_with(SOURCE), "{err}");
    assert!(err.contains(want), "wanted {want:?} in: {err}");
}

fn compacted(mut tree: BuildTree) -> BuildTree {
    tree.compact();
    tree
}

/// Rewrites the header checksum after a deliberate change to the header.
fn reseal_header(bytes: &mut [u8]) {
    let crc = crc32fast_hash(&bytes[..60]);
    bytes[60..64].copy_from_slice(&crc.to_le_bytes());
}

/// Rewrites the payload checksum (and the header's) after a deliberate change to the payload:
/// the file is then well-sealed but lies, as a hostile file would.
fn reseal(bytes: &mut [u8]) {
    let crc = crc32fast_hash(&bytes[64..]);
    bytes[56..60].copy_from_slice(&crc.to_le_bytes());
    reseal_header(bytes);
}

/// CRC-32 (IEEE), written out so the tests do not lean on the code under test.
fn crc32fast_hash(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in bytes {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

#[test]
fn round_trip_gives_the_same_tree_mesh_and_settings() {
    let mesh = icosphere(Vec3::ZERO, 1.0, 3);
    let mut tree = InsertionBuilder::default().build(&mesh);
    ReinsertionOptimizer::default().optimize(&mut tree);
    let file = saved(&mesh, tree);
    let loaded = load(&file.to_bytes()).unwrap();
    assert_eq!(loaded.mesh, file.mesh);
    assert_eq!(loaded.settings, file.settings);
    assert_eq!(compacted(loaded.tree), compacted(file.tree));
}

#[test]
fn an_empty_mesh_and_tree_round_trip() {
    let mesh = hbv::TriangleMesh::default();
    let file = saved(&mesh, BuildTree::new());
    let loaded = load(&file.to_bytes()).unwrap();
    assert!(loaded.tree.is_empty() && loaded.mesh.is_empty());
}

#[test]
fn files_are_recognized_by_their_magic_not_their_name() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("tree.bin");
    std::fs::write(&path, sample().to_bytes()).unwrap();
    assert!(is_bvh_file(&path));
    let obj = dir.path().join("tree.hbv");
    std::fs::write(&obj, "v 0 0 0\n").unwrap();
    assert!(!is_bvh_file(&obj));
    assert!(!is_bvh_file(dir.path().join("missing.hbv")));
}

/// `BvhFile::save` (the one path of `hbv build` and `BVH.save`) writes what `to_bytes` gives,
/// reports its size, and replaces a file only when asked.
#[test]
fn save_writes_the_bytes_and_replaces_only_when_asked() {
    use hbv::atomic_file::Replace;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("tree.hbv");
    let file = sample();
    let bytes = file.save(&path, Replace::Never).unwrap();
    assert_eq!(std::fs::read(&path).unwrap(), file.to_bytes());
    assert_eq!(bytes, file.to_bytes().len() as u64);
    let e = file.save(&path, Replace::Never).unwrap_err();
    assert_eq!(e.kind(), std::io::ErrorKind::AlreadyExists);
    assert!(e.to_string().contains("tree.hbv"), "{e}");
    std::fs::write(&path, b"old").unwrap();
    file.save(&path, Replace::Always).unwrap();
    assert_eq!(std::fs::read(&path).unwrap(), file.to_bytes());
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

/// A saved icosphere of about 80k triangles, above 1 MiB (files that large were memory-mapped).
fn large_file() -> BvhFile {
    let mesh = icosphere(Vec3::ZERO, 1.0, 6);
    saved(&mesh, BinnedSahBuilder::default().build(&mesh))
}

#[test]
fn large_files_load_and_a_truncated_one_is_an_error() {
    let file = large_file();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("big.hbv");
    let bytes = file.to_bytes();
    assert!(bytes.len() > 1 << 20);
    std::fs::write(&path, &bytes).unwrap();
    let loaded = BvhFile::load(&path).unwrap();
    assert_eq!(compacted(loaded.tree), compacted(file.tree));
    std::fs::write(&path, &bytes[..bytes.len() / 2]).unwrap();
    let err = BvhFile::load(&path).unwrap_err().to_string();
    assert!(err.starts_with(&path.display().to_string()), "{err}");
    assert!(err.contains("truncated: it ends in the"), "{err}");
}

/// Another process truncating or rewriting a file while it loads made the memory-mapped reader
/// die of SIGBUS (27 of 40 tries). Here a thread truncates the file and writes it back in place,
/// over and over, while it is loaded: every load must give the tree or an error naming the file.
/// (Before the fix this test process was killed; the race is timing-dependent, so a pass on the
/// old code was possible, though unlikely over this many loads.)
#[test]
fn a_file_rewritten_while_it_loads_gives_the_tree_or_an_error() {
    use std::io::{Seek, Write};
    use std::sync::atomic::{AtomicBool, Ordering};
    let file = large_file();
    let bytes = file.to_bytes();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("changing.hbv");
    std::fs::write(&path, &bytes).unwrap();
    let stop = AtomicBool::new(false);
    let (mut trees, mut errors) = (0, 0);
    std::thread::scope(|scope| {
        scope.spawn(|| {
            let mut f = std::fs::OpenOptions::new().write(true).open(&path).unwrap();
            while !stop.load(Ordering::Relaxed) {
                f.set_len(0).unwrap();
                f.rewind().unwrap();
                f.write_all(&bytes).unwrap();
            }
        });
        let start = std::time::Instant::now();
        while start.elapsed().as_secs_f64() < 2.0 || trees + errors < 20 {
            match BvhFile::load(&path) {
                Ok(loaded) => {
                    assert_eq!(loaded.mesh, file.mesh);
                    trees += 1;
                }
                Err(e) => {
                    let message = e.to_string();
                    assert!(
                        message.starts_with(&path.display().to_string()),
                        "{message}"
                    );
                    errors += 1;
                }
            }
        }
        stop.store(true, Ordering::Relaxed);
    });
    assert!(trees + errors >= 20);
}

/// `/dev/zero` under a `.hbv` name was read for ever.
#[cfg(unix)]
#[test]
fn a_device_is_refused_not_read_for_ever() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("zero.hbv");
    std::os::unix::fs::symlink("/dev/zero", &path).unwrap();
    let err = BvhFile::load(&path).unwrap_err().to_string();
    assert!(
        err.ends_with("zero.hbv: a device or a socket, not a .hbv file"),
        "{err}"
    );
}

#[test]
fn a_missing_file_is_named() {
    let err = BvhFile::load("/nonexistent/dir/x.hbv")
        .unwrap_err()
        .to_string();
    assert!(err.starts_with("/nonexistent/dir/x.hbv: "), "{err}");
}

#[test]
fn truncation_anywhere_names_the_section_it_ends_in() {
    let bytes = sample().to_bytes();
    let f = sample();
    let v = f.mesh.positions().len();
    let t = f.mesh.triangle_count();
    let settings_end = 64 + f.settings.len().next_multiple_of(4);
    let positions_end = settings_end + 12 * v;
    let triangles_end = positions_end + 12 * t;
    let nodes_end = bytes.len() - 4 * t; // every triangle is in one leaf entry
    let cases = [
        (4, "not an hbv BVH file"),
        (8, "truncated: it ends in the header"),
        (63, "truncated: it ends in the header"),
        (64, "ends in the settings"),
        (settings_end + 5, "ends in the positions"),
        (positions_end + 11, "ends in the triangles"),
        (triangles_end + 31, "ends in the nodes"),
        (nodes_end + 3, "ends in the leaf entries"),
        (bytes.len() - 1, "ends in the leaf entries"),
    ];
    for (len, want) in cases {
        assert_fails(&bytes[..len], want);
    }
    for len in 0..bytes.len() {
        assert!(load(&bytes[..len]).is_err(), "{len} bytes");
    }
}

#[test]
fn trailing_bytes_are_refused() {
    let mut bytes = sample().to_bytes();
    bytes.extend_from_slice(&[0; 4]);
    assert_fails(&bytes, "4 unexpected bytes after the end of the data");
}

#[test]
fn a_flipped_byte_anywhere_is_caught() {
    let bytes = sample().to_bytes();
    assert_fails(
        &[b"v 0 0 0\n".as_slice(), &bytes[8..]].concat(),
        "not an hbv BVH file",
    );
    for at in (0..bytes.len()).step_by(7).chain([60, 64, bytes.len() - 1]) {
        let mut bad = bytes.clone();
        bad[at] ^= 0x10;
        let err = load(&bad).expect_err("a flipped byte").to_string();
        assert!(err.starts_with(SOURCE), "{err}");
    }
    let mut bad = bytes.clone();
    bad[100] ^= 1;
    assert_fails(&bad, "the payload is corrupted: CRC-32");
    let mut bad = bytes.clone();
    bad[30] ^= 1;
    assert_fails(&bad, "the header is corrupted: CRC-32");
}

#[test]
fn foreign_and_future_files_are_named_as_such() {
    let bytes = sample().to_bytes();
    assert_fails(b"", "not an hbv BVH file");
    assert_fails(b"ply\nformat ascii 1.0\n", "not an hbv BVH file");
    let mut future = bytes.clone();
    future[8..12].copy_from_slice(&(FORMAT_VERSION + 1).to_le_bytes());
    assert_fails(
        &future,
        &format!(
            "format version {} is newer than this hbv reads ({FORMAT_VERSION})",
            FORMAT_VERSION + 1
        ),
    );
    let mut zero = bytes.clone();
    zero[8..12].copy_from_slice(&0u32.to_le_bytes());
    assert_fails(&zero, "unknown format version 0");
    let mut big_endian = bytes.clone();
    big_endian[12..16].copy_from_slice(&0x0102_0304u32.to_be_bytes());
    reseal_header(&mut big_endian);
    assert_fails(&big_endian, "wrong byte-order mark 0x04030201");
    assert_eq!(&bytes[..8], &MAGIC);
}

#[test]
fn sizes_that_lie_are_caught_before_anything_is_allocated() {
    let bytes = sample().to_bytes();
    let lie = |offset: usize, value: u64, want: &str| {
        let mut bad = bytes.clone();
        if offset == 20 {
            bad[20..24].copy_from_slice(&(value as u32).to_le_bytes());
        } else {
            bad[offset..offset + 8].copy_from_slice(&value.to_le_bytes());
        }
        reseal_header(&mut bad);
        assert_fails(&bad, want);
    };
    // Counts that would need terabytes: refused from the length alone.
    lie(24, 1 << 40, "ends in the positions");
    lie(32, u64::MAX / 4, "impossible size for the triangles");
    lie(40, u64::MAX, "impossible size for the nodes");
    lie(48, 1 << 62, "impossible size for the leaf entries");
    lie(20, 1 << 20, "impossible size for the settings");
    // Counts one smaller: the sections no longer end where the file does.
    let v = sample().mesh.positions().len() as u64;
    lie(24, v - 1, "unexpected bytes after the end of the data");
}

/// Offset of node `k`'s record in `sample()`'s bytes.
fn node_offset(file: &BvhFile, k: usize) -> usize {
    64 + file.settings.len().next_multiple_of(4)
        + 12 * file.mesh.positions().len()
        + 12 * file.mesh.triangle_count()
        + 32 * k
}

#[test]
fn well_sealed_files_that_describe_a_broken_tree_are_refused() {
    let file = sample();
    let bytes = file.to_bytes();
    let n = (bytes.len() - node_offset(&file, 0) - 4 * file.mesh.triangle_count()) / 32;
    let edit = |k: usize, field: usize, value: u32, want: &str| {
        let mut bad = bytes.clone();
        let at = node_offset(&file, k) + field;
        bad[at..at + 4].copy_from_slice(&value.to_le_bytes());
        reseal(&mut bad);
        assert_fails(&bad, want);
    };
    let leaf = (0..n)
        .find(|&k| bytes[node_offset(&file, k) + 31] & 0x80 != 0)
        .unwrap();
    // first / count of the root (internal) and of a leaf.
    edit(0, 24, 0, "node 0: a child does not come after its parent");
    edit(
        0,
        24,
        n as u32,
        "node 0: its children lie past the end of the nodes",
    );
    edit(0, 28, 0, "node 0: is empty");
    edit(0, 28, 1, "is not in the tree");
    edit(leaf, 24, u32::MAX, "lie past the end of the leaf entries");
    // A box that does not hold its triangle.
    edit(leaf, 0, f32::to_bits(1e30), "tree invariant broken");
    edit(leaf, 12, f32::to_bits(f32::NAN), "tree invariant broken");
    // A triangle id out of range.
    let mut bad = bytes.clone();
    let last = bad.len() - 4;
    bad[last..].copy_from_slice(&u32::MAX.to_le_bytes());
    reseal(&mut bad);
    assert_fails(&bad, "triangle 4294967295 is out of range");
    // A vertex index out of range, and a vertex that is not finite.
    let mut bad = bytes.clone();
    let tri = node_offset(&file, 0) - 12 * file.mesh.triangle_count();
    bad[tri..tri + 4].copy_from_slice(&u32::MAX.to_le_bytes());
    reseal(&mut bad);
    assert_fails(&bad, "mesh: ");
    let mut bad = bytes.clone();
    let pos = 64 + file.settings.len().next_multiple_of(4);
    bad[pos..pos + 4].copy_from_slice(&f32::NAN.to_le_bytes());
    reseal(&mut bad);
    assert_fails(&bad, "not finite");
    // Settings that are not UTF-8.
    let mut bad = bytes.clone();
    bad[64] = 0xff;
    reseal(&mut bad);
    assert_fails(&bad, "settings: not UTF-8");
}

proptest! {
    #![proptest_config(common::cases(32))]

    #[test]
    fn any_saved_tree_answers_as_before((mesh, rays) in mesh_and_rays(soup()), leaf in 1u32..5) {
        let mut config = hbv::bvh::build::BinnedSahConfig::default();
        config.leaf.max_leaf_size = leaf as usize;
        let tree = BinnedSahBuilder::new(config).build(&mesh);
        let file = saved(&mesh, tree);
        let loaded = load(&file.to_bytes()).unwrap();
        prop_assert_eq!(compacted(loaded.tree.clone()), compacted(file.tree));
        assert_agrees(&mesh, &RecursiveLayout::new(&loaded.tree, &loaded.mesh), &rays)?;
    }
}

#[test]
fn every_structural_check_has_its_message() {
    let file = sample();
    let bytes = file.to_bytes();
    let n = (bytes.len() - node_offset(&file, 0) - 4 * file.mesh.triangle_count()) / 32;
    let field = |bytes: &[u8], k: usize, at: usize| {
        let o = node_offset(&file, k) + at;
        u32::from_le_bytes(bytes[o..o + 4].try_into().unwrap())
    };
    let edit = |k: usize, at: usize, value: u32, want: &str| {
        let mut bad = bytes.clone();
        let o = node_offset(&file, k) + at;
        bad[o..o + 4].copy_from_slice(&value.to_le_bytes());
        reseal(&mut bad);
        assert_fails(&bad, want);
    };
    let is_leaf = |k: usize| field(&bytes, k, 28) & (1 << 31) != 0;
    let count = |k: usize| field(&bytes, k, 28) & !(1 << 31);
    // The root's children are 1 and 2, and node 1's come next: a root claiming one more child
    // shares it with node 1.
    assert!(!is_leaf(0) && !is_leaf(1) && count(0) == 2 && field(&bytes, 0, 24) == 1);
    edit(0, 28, 3, "node 1: child 3 has two parents");
    let leaves: Vec<usize> = (0..n).filter(|&k| is_leaf(k)).collect();
    let (a, b) = (leaves[0], leaves[1]);
    edit(b, 24, field(&bytes, a, 24), "is used twice");
    let wide = *leaves.iter().find(|&&k| count(k) >= 2).unwrap();
    edit(
        wide,
        28,
        (count(wide) - 1) | (1 << 31),
        "belongs to no leaf",
    );
    edit(wide, 28, 1 << 31, "is empty");

    let mut bad = bytes.clone();
    bad[16..20].copy_from_slice(&65u32.to_le_bytes());
    reseal_header(&mut bad);
    assert_fails(&bad, "header: header size is not 64");

    let mut bad = saved(&hbv::TriangleMesh::default(), BuildTree::new()).to_bytes();
    bad[48..56].copy_from_slice(&1u64.to_le_bytes());
    bad.extend_from_slice(&0u32.to_le_bytes());
    reseal(&mut bad);
    assert_fails(&bad, "leaf entries: present in a file without nodes");
}
