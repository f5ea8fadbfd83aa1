//! Approximate convex decomposition of object meshes, and the on-disk cache of its results.
//!
//! Decomposition is expensive (a tenth of a second to seconds per mesh), so every result is
//! written to a cache folder under a key made of the mesh's exact contents and the decomposer
//! settings; the second build of a scene reads hulls instead of recomputing them. The in-process
//! backend is parry's V-HACD port. CoACD (the paper's choice) has no Rust port: its entries are
//! written offline by `python/tools/coacd_cache.py` in the same format, under keys computed
//! here (`sage3d physics pending` lists the meshes it still has to do).
//!
//! A cache only ever saves work: an entry that cannot be read as its key's (another magic or
//! format version, another key, cut short or with bytes to spare, a coordinate that is not
//! finite, a triangle index past its part's vertices) is [`CacheEntry::Damaged`], and a build
//! makes it anew and replaces it as it would a missing one, reporting the file
//! ([`crate::BuildReport::remade`]), where an error would stop every build of the scene until
//! someone removed the file by hand.
//!
//! File format (little endian), one file `{key}.hulls` per entry:
//! `b"SAGEHULL"`, `u32` version (1), 16-byte key, `u32` part count, then per part `u32` vertex
//! count `n`, `u32` triangle count `m`, `n × 3 f32` positions, `m × 3 u32` indices.

use crate::hull::ConvexPart;
use glam::Vec3;
use parry3d::transformation::vhacd::{VHACD, VHACDParameters};
use sage_core::{Error, Result, ResultExt};
use sage_io::files::write_atomic;
use sage_scene::TriMesh;
use std::io::Write;
use std::path::{Path, PathBuf};

/// First bytes of a cache file.
pub const MAGIC: &[u8; 8] = b"SAGEHULL";
/// Version of the cache file format.
pub const VERSION: u32 = 1;
/// File extension of cache entries.
pub const EXTENSION: &str = "hulls";

/// Which decomposer made (or must make) the hulls, with its settings. Part of the cache key.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Decomposer {
    /// parry's V-HACD, run in process.
    Vhacd {
        /// Voxels along the longest axis (64 is the practical default; cost grows ~8× per doubling).
        resolution: u32,
        /// Maximum concavity per part (parry's default 0.01).
        concavity: f32,
        /// Cap on the number of parts.
        max_hulls: u32,
    },
    /// CoACD (PyPI `coacd`), run offline by `python/tools/coacd_cache.py`.
    Coacd {
        /// CoACD's concavity threshold (its default 0.05).
        threshold: f32,
        /// Cap on the number of parts (CoACD's `max_convex_hull`; 0 for no cap).
        max_hulls: u32,
    },
}

impl Default for Decomposer {
    fn default() -> Self {
        Decomposer::Vhacd {
            resolution: 64,
            concavity: 0.01,
            max_hulls: 32,
        }
    }
}

impl Decomposer {
    /// The backend name (`vhacd` or `coacd`).
    pub fn backend(&self) -> &'static str {
        match self {
            Decomposer::Vhacd { .. } => "vhacd",
            Decomposer::Coacd { .. } => "coacd",
        }
    }

    /// The settings as canonical text; it enters the cache key, so any change makes a new key.
    pub fn describe(&self) -> String {
        match *self {
            Decomposer::Vhacd {
                resolution,
                concavity,
                max_hulls,
            } => {
                format!("vhacd;resolution={resolution};concavity={concavity};max_hulls={max_hulls}")
            }
            Decomposer::Coacd {
                threshold,
                max_hulls,
            } => format!("coacd;threshold={threshold};max_hulls={max_hulls}"),
        }
    }

    /// Checks the settings' ranges.
    pub fn validate(&self) -> Result<()> {
        let ok = match *self {
            Decomposer::Vhacd {
                resolution,
                concavity,
                max_hulls,
            } => {
                (8..=512).contains(&resolution)
                    && concavity.is_finite()
                    && concavity > 0.0
                    && max_hulls >= 1
            }
            Decomposer::Coacd { threshold, .. } => {
                threshold.is_finite() && (0.01..=1.0).contains(&threshold)
            }
        };
        if ok {
            Ok(())
        } else {
            Err(Error::invalid(format!(
                "decomposer settings out of range: {} (V-HACD resolution 8-512, concavity > 0, \
                 max_hulls >= 1; CoACD threshold 0.01-1)",
                self.describe()
            )))
        }
    }

    /// Decomposes `mesh` in process. Only V-HACD runs here; CoACD entries must already be in
    /// the cache.
    pub fn run(&self, mesh: &TriMesh) -> Result<Vec<ConvexPart>> {
        match *self {
            Decomposer::Vhacd {
                resolution,
                concavity,
                max_hulls,
            } => Ok(vhacd(mesh, resolution, concavity, max_hulls)),
            Decomposer::Coacd { .. } => Err(Error::invalid(
                "CoACD hulls are made offline: `sage3d physics pending SCENE --backend coacd \
                 --out todo.json` lists the meshes, `python python/tools/coacd_cache.py \
                 todo.json` fills the cache, then build again",
            )),
        }
    }
}

fn vhacd(mesh: &TriMesh, resolution: u32, concavity: f32, max_hulls: u32) -> Vec<ConvexPart> {
    let params = VHACDParameters {
        resolution,
        concavity,
        max_convex_hulls: max_hulls,
        ..VHACDParameters::default()
    };
    let decomposition = VHACD::decompose(&params, &mesh.positions, &mesh.triangles, true);
    decomposition
        .compute_exact_convex_hulls(&mesh.positions, &mesh.triangles)
        .into_iter()
        .filter_map(|(vertices, _)| ConvexPart::hull_of(&vertices))
        .collect()
}

/// The cache key of (mesh, decomposer): FNV-1a 128 over the settings text, the vertex and
/// triangle counts, every coordinate's bits and every index (little endian).
pub fn cache_key(mesh: &TriMesh, decomposer: &Decomposer) -> u128 {
    let mut h = sage_io::hash::Fnv1a128::new();
    h.write(decomposer.describe().as_bytes());
    h.write(&(mesh.positions.len() as u64).to_le_bytes());
    h.write(&(mesh.triangles.len() as u64).to_le_bytes());
    for p in &mesh.positions {
        for c in p.to_array() {
            h.write(&c.to_bits().to_le_bytes());
        }
    }
    for t in &mesh.triangles {
        for i in t {
            h.write(&i.to_le_bytes());
        }
    }
    h.finish()
}

/// What a [`HullCache`] holds under one key.
#[derive(Debug)]
pub enum CacheEntry {
    /// The parts stored under the key.
    Parts(Vec<ConvexPart>),
    /// No entry: the key's mesh has not been decomposed with these settings.
    Missing,
    /// An entry that is not a whole cache file of the key (as the module's documentation lists):
    /// the format error, naming the file. It is to be made again, as a missing one.
    Damaged(Error),
}

/// A folder of cached decompositions, one file per key.
#[derive(Debug, Clone, PartialEq)]
pub struct HullCache {
    dir: PathBuf,
}

/// Where a scene keeps its cache unless told otherwise: `<scene>/.sage3d/collision`.
pub fn default_cache_dir(scene_dir: &Path) -> PathBuf {
    scene_dir.join(".sage3d").join("collision")
}

impl HullCache {
    /// A cache in `dir` (created on the first write).
    pub fn new(dir: impl Into<PathBuf>) -> Self {
        HullCache { dir: dir.into() }
    }

    /// The folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// An error naming the cache when its path is a file (the system's own error, "not a
    /// directory", would name an entry's path inside it).
    fn check_folder(&self) -> Result<()> {
        if self.dir.exists() && !self.dir.is_dir() {
            return Err(Error::invalid(
                "the hull cache is a file, not a folder: give a folder (or none, for the scene's own)",
            )
            .in_file(&self.dir));
        }
        Ok(())
    }

    /// The file of `key`.
    pub fn path(&self, key: u128) -> PathBuf {
        self.dir.join(format!("{key:032x}.{EXTENSION}"))
    }

    /// Reads the entry of `key`: its parts, [`CacheEntry::Missing`], or
    /// [`CacheEntry::Damaged`] with the error that names the file and what is wrong.
    ///
    /// # Errors
    ///
    /// The cache is a file, or the entry exists but cannot be read (permissions).
    pub fn load(&self, key: u128) -> Result<CacheEntry> {
        self.check_folder()?;
        let path = self.path(key);
        let bytes = match std::fs::read(&path) {
            Ok(b) => b,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(CacheEntry::Missing),
            Err(e) => return Err(Error::io(&path, e)),
        };
        Ok(match decode(&bytes, key).in_file(&path) {
            Ok(parts) => CacheEntry::Parts(parts),
            Err(e) => CacheEntry::Damaged(e),
        })
    }

    /// Writes the entry of `key` atomically.
    pub fn store(&self, key: u128, parts: &[ConvexPart]) -> Result<()> {
        self.check_folder()?;
        std::fs::create_dir_all(&self.dir).map_err(|e| Error::io(&self.dir, e))?;
        let bytes = encode(key, parts);
        write_atomic(&self.path(key), |w| w.write_all(&bytes))
    }
}

/// Serialises parts in the cache format.
pub fn encode(key: u128, parts: &[ConvexPart]) -> Vec<u8> {
    let mut out = Vec::new();
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&VERSION.to_le_bytes());
    out.extend_from_slice(&key.to_le_bytes());
    out.extend_from_slice(&(parts.len() as u32).to_le_bytes());
    for p in parts {
        out.extend_from_slice(&(p.vertices.len() as u32).to_le_bytes());
        out.extend_from_slice(&(p.triangles.len() as u32).to_le_bytes());
        for v in &p.vertices {
            for c in v.to_array() {
                out.extend_from_slice(&c.to_le_bytes());
            }
        }
        for t in &p.triangles {
            for i in t {
                out.extend_from_slice(&i.to_le_bytes());
            }
        }
    }
    out
}

struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take(&mut self, n: usize, what: &str) -> Result<&[u8]> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.bytes.len());
        let end = end.ok_or_else(|| {
            Error::format(
                what,
                format!("truncated at byte {} of {}", self.at, self.bytes.len()),
            )
        })?;
        let s = &self.bytes[self.at..end];
        self.at = end;
        Ok(s)
    }

    fn u32(&mut self, what: &str) -> Result<u32> {
        let b = self.take(4, what)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    fn f32(&mut self, what: &str) -> Result<f32> {
        self.u32(what).map(f32::from_bits)
    }
}

/// Parses a cache file and checks it holds `key`.
pub fn decode(bytes: &[u8], key: u128) -> Result<Vec<ConvexPart>> {
    let mut r = Reader { bytes, at: 0 };
    if r.take(8, "magic")? != MAGIC {
        return Err(Error::format("magic", "not a sage3d hull cache file"));
    }
    let version = r.u32("version")?;
    if version != VERSION {
        return Err(Error::format(
            "version",
            format!("expected {VERSION}, found {version}"),
        ));
    }
    let stored = u128::from_le_bytes(r.take(16, "key")?.try_into().unwrap_or([0; 16]));
    if stored != key {
        return Err(Error::format(
            "key",
            format!("holds {stored:032x}, expected {key:032x}"),
        ));
    }
    let count = r.u32("parts")?;
    let mut parts = Vec::new();
    for pi in 0..count {
        let at = format!("parts[{pi}]");
        let nv = r.u32(&at)? as usize;
        let nt = r.u32(&at)? as usize;
        // Counts are checked against the bytes left before anything is allocated.
        if nv.saturating_mul(12).saturating_add(nt.saturating_mul(12)) > bytes.len() - r.at {
            return Err(Error::format(at, "counts exceed the file size"));
        }
        let mut vertices = Vec::with_capacity(nv);
        for _ in 0..nv {
            let v = Vec3::new(r.f32(&at)?, r.f32(&at)?, r.f32(&at)?);
            if !v.is_finite() {
                return Err(Error::format(at, "vertex coordinate is not finite"));
            }
            vertices.push(v);
        }
        let mut triangles = Vec::with_capacity(nt);
        for _ in 0..nt {
            let t = [r.u32(&at)?, r.u32(&at)?, r.u32(&at)?];
            if t.iter().any(|&i| i as usize >= nv) {
                return Err(Error::format(at, "triangle index out of range"));
            }
            triangles.push(t);
        }
        parts.push(ConvexPart {
            vertices,
            triangles,
        });
    }
    if r.at != bytes.len() {
        return Err(Error::format(
            "end",
            format!("{} trailing bytes", bytes.len() - r.at),
        ));
    }
    Ok(parts)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn cube(size: f32) -> TriMesh {
        let part = ConvexPart::from_obb(&sage_core::Obb {
            center: Vec3::splat(size * 0.5),
            half_extents: Vec3::splat(size * 0.5),
            yaw: 0.0,
        })
        .unwrap();
        part.as_mesh()
    }

    #[test]
    fn key_changes_with_mesh_and_settings() {
        let d = Decomposer::default();
        let a = cache_key(&cube(1.0), &d);
        assert_eq!(a, cache_key(&cube(1.0), &d));
        assert_ne!(a, cache_key(&cube(1.1), &d));
        let other = Decomposer::Vhacd {
            resolution: 32,
            concavity: 0.01,
            max_hulls: 32,
        };
        assert_ne!(a, cache_key(&cube(1.0), &other));
    }

    #[test]
    fn cache_round_trips_and_rejects_a_foreign_key() {
        let dir = tempfile::tempdir().unwrap();
        let cache = HullCache::new(dir.path().join("c"));
        let parts = vec![ConvexPart::hull_of(&cube(1.0).positions).unwrap()];
        assert!(matches!(cache.load(7).unwrap(), CacheEntry::Missing));
        cache.store(7, &parts).unwrap();
        assert!(matches!(cache.load(7).unwrap(), CacheEntry::Parts(p) if p == parts));
        std::fs::copy(cache.path(7), cache.path(8)).unwrap();
        let CacheEntry::Damaged(e) = cache.load(8).unwrap() else {
            panic!("an entry holding another key is damaged");
        };
        let e = e.to_string();
        assert!(e.contains("key") && e.contains(".hulls"), "{e}");
        let file = dir.path().join("a file");
        std::fs::write(&file, "x").unwrap();
        let cache = HullCache::new(&file);
        for e in [
            cache.load(7).unwrap_err(),
            cache.store(7, &parts).unwrap_err(),
        ] {
            let e = e.to_string();
            assert!(
                e.starts_with(&format!("{}: the hull cache is a file", file.display())),
                "{e}"
            );
        }
    }

    /// Every way an entry can fail to be its key's whole file is [`CacheEntry::Damaged`],
    /// saying what is wrong; the same entry whole is read.
    #[test]
    fn each_kind_of_damage_is_told() {
        let dir = tempfile::tempdir().unwrap();
        let cache = HullCache::new(dir.path());
        let part = ConvexPart::hull_of(&cube(1.0).positions).unwrap();
        let whole = encode(5, std::slice::from_ref(&part));
        // Offsets: magic 0, version 8, key 12, part count 28, the part's counts 32 and 36,
        // its vertices from 40, its triangles after them.
        let triangles = 40 + 12 * part.vertices.len();
        let patch = |at: usize, bytes: &[u8]| {
            let mut b = whole.clone();
            b[at..at + bytes.len()].copy_from_slice(bytes);
            b
        };
        let mut trailing = whole.clone();
        trailing.push(0);
        let nv = part.vertices.len() as u32;
        for (bytes, told) in [
            (patch(0, b"NOTHULLS"), "not a sage3d hull cache file"),
            (patch(8, &2u32.to_le_bytes()), "expected 1, found 2"),
            (
                patch(12, &6u128.to_le_bytes()),
                "expected 00000000000000000000000000000005",
            ),
            (whole[..20].to_vec(), "truncated at byte 12 of 20"),
            (
                whole[..whole.len() - 1].to_vec(),
                "counts exceed the file size",
            ),
            (trailing, "1 trailing bytes"),
            (patch(40, &f32::NAN.to_le_bytes()), "not finite"),
            (patch(triangles, &nv.to_le_bytes()), "index out of range"),
        ] {
            std::fs::write(cache.path(5), &bytes).unwrap();
            match cache.load(5).unwrap() {
                CacheEntry::Damaged(e) => {
                    let e = e.to_string();
                    assert!(e.contains(told) && e.contains(".hulls"), "{told}: {e}");
                }
                other => panic!("{told}: {other:?}"),
            }
        }
        std::fs::write(cache.path(5), &whole).unwrap();
        assert!(matches!(cache.load(5).unwrap(), CacheEntry::Parts(p) if p == [part]));
    }

    #[test]
    fn coacd_is_not_run_in_process() {
        let d = Decomposer::Coacd {
            threshold: 0.05,
            max_hulls: 0,
        };
        assert!(d.run(&cube(1.0)).is_err());
    }

    proptest! {
        #[test]
        fn damaged_files_give_errors_not_panics(
            cut in 0usize..200, flip in 0usize..200, byte in any::<u8>()
        ) {
            let parts = vec![ConvexPart::hull_of(&cube(0.5).positions).unwrap()];
            let mut bytes = encode(3, &parts);
            let n = bytes.len();
            bytes[flip % n] ^= byte;
            bytes.truncate(n - cut % n);
            let _ = decode(&bytes, 3);
        }
    }
}
