//! On-disk cache of the template's tetrahedral mesh, keyed by content: a 64-bit FNV-1a hash
//! (Fowler, Noll & Vo) of the surface's vertices and faces, the stuffing parameters and
//! [`ALGORITHM_VERSION`]. Files are written atomically ([`crate::io::atomic`]) and never
//! trusted blindly: a file whose size, key, counts, indices or coordinates do not check out is
//! ignored (and rebuilt by the caller).
//!
//! File layout (little-endian): magic `ERGOTET\0`, key `u64`, node count `u64`, tetrahedron
//! count `u64`, nodes as `3 × f64`, tetrahedra as `4 × u32`.

use super::stuffing::{StuffingParams, ALGORITHM_VERSION};
use crate::error::Result;
use crate::geometry::tet_mesh::TetMesh;
use crate::geometry::{Point, TriMesh};
use crate::io::atomic::write_bytes_atomic;
use std::path::{Path, PathBuf};

const MAGIC: &[u8; 8] = b"ERGOTET\0";
const HEADER: usize = 8 + 3 * 8;

/// FNV-1a, 64 bit: a stable hash (unlike `std`'s, which may change between releases).
struct Fnv(u64);

impl Fnv {
    fn new() -> Self {
        Fnv(0xcbf2_9ce4_8422_2325)
    }
    fn bytes(&mut self, b: &[u8]) {
        for &x in b {
            self.0 ^= x as u64;
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    fn u64(&mut self, x: u64) {
        self.bytes(&x.to_le_bytes());
    }
    fn f64(&mut self, x: f64) {
        self.u64(x.to_bits());
    }
}

/// The cache key of stuffing `surface` with `params`.
pub fn cache_key(surface: &TriMesh, params: &StuffingParams) -> u64 {
    let mut h = Fnv::new();
    h.u64(ALGORITHM_VERSION as u64);
    h.f64(params.spacing);
    h.f64(params.alpha_long);
    h.f64(params.alpha_short);
    h.u64(surface.vertices.len() as u64);
    for p in &surface.vertices {
        h.f64(p.x);
        h.f64(p.y);
        h.f64(p.z);
    }
    h.u64(surface.faces.len() as u64);
    for f in &surface.faces {
        for &v in f {
            h.u64(v as u64);
        }
    }
    h.0
}

/// The default cache folder: `$ERGOHAND_CACHE`, else `$XDG_CACHE_HOME/ergohand`, else
/// `~/.cache/ergohand` (`None` when none of these variables is set).
pub fn default_cache_dir() -> Option<PathBuf> {
    let var = |k: &str| {
        std::env::var_os(k)
            .filter(|v| !v.is_empty())
            .map(PathBuf::from)
    };
    var("ERGOHAND_CACHE")
        .or_else(|| var("XDG_CACHE_HOME").map(|d| d.join("ergohand")))
        .or_else(|| var("HOME").map(|d| d.join(".cache").join("ergohand")))
}

/// The cache file of `key` in `dir`.
pub(crate) fn cache_path(dir: &Path, key: u64) -> PathBuf {
    dir.join(format!("tet-{key:016x}.bin"))
}

/// Serialise `mesh` under `key`.
pub fn encode(mesh: &TetMesh, key: u64) -> Vec<u8> {
    let mut b = Vec::with_capacity(HEADER + 24 * mesh.n_nodes() + 16 * mesh.n_tets());
    b.extend_from_slice(MAGIC);
    b.extend_from_slice(&key.to_le_bytes());
    b.extend_from_slice(&(mesh.n_nodes() as u64).to_le_bytes());
    b.extend_from_slice(&(mesh.n_tets() as u64).to_le_bytes());
    for p in &mesh.nodes {
        for c in [p.x, p.y, p.z] {
            b.extend_from_slice(&c.to_le_bytes());
        }
    }
    for t in &mesh.tets {
        for &v in t {
            b.extend_from_slice(&(v as u32).to_le_bytes());
        }
    }
    b
}

/// Parse a cache file's bytes; `None` unless everything checks out: magic, `key`, the size
/// implied by the counts (checked before allocating), node indices and finite coordinates.
pub fn decode(bytes: &[u8], key: u64) -> Option<TetMesh> {
    if bytes.len() < HEADER || &bytes[..8] != MAGIC {
        return None;
    }
    let word = |i: usize| u64::from_le_bytes(bytes[i..i + 8].try_into().unwrap_or([0; 8]));
    let (k, n, t) = (word(8), word(16), word(24));
    if k != key || n > u32::MAX as u64 {
        return None;
    }
    let size = (HEADER as u128) + 24 * n as u128 + 16 * t as u128;
    if size != bytes.len() as u128 {
        return None;
    }
    let (n, t) = (n as usize, t as usize);
    let f = |i: usize| f64::from_le_bytes(bytes[i..i + 8].try_into().unwrap_or([0; 8]));
    let nodes: Vec<Point> = (0..n)
        .map(|i| {
            let o = HEADER + 24 * i;
            Point::new(f(o), f(o + 8), f(o + 16))
        })
        .collect();
    let base = HEADER + 24 * n;
    let tets: Vec<[usize; 4]> = (0..t)
        .map(|i| {
            std::array::from_fn(|c| {
                let o = base + 16 * i + 4 * c;
                u32::from_le_bytes(bytes[o..o + 4].try_into().unwrap_or([0; 4])) as usize
            })
        })
        .collect();
    let mesh = TetMesh::new(nodes, tets).ok()?;
    (mesh.n_tets() > 0).then_some(mesh)
}

/// Read the cached mesh of `key` from `dir`, if present and valid.
pub fn load(dir: &Path, key: u64) -> Option<TetMesh> {
    let bytes = std::fs::read(cache_path(dir, key)).ok()?;
    decode(&bytes, key)
}

/// Write `mesh` to the cache (creating `dir`), atomically.
pub fn store(dir: &Path, key: u64, mesh: &TetMesh) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| crate::error::Error::io(dir, e))?;
    write_bytes_atomic(&cache_path(dir, key), &encode(mesh, key))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::mesh::tests::cuboid;
    use crate::tet::template_tet_mesh_with;

    #[test]
    fn key_depends_on_content_and_parameters() {
        let c = cuboid(10.0, 10.0, 10.0);
        let p = StuffingParams::with_spacing(2.0);
        let k = cache_key(&c, &p);
        assert_eq!(k, cache_key(&c.clone(), &p));
        assert_ne!(k, cache_key(&c, &StuffingParams::with_spacing(2.5)));
        let mut moved = c.clone();
        moved.vertices[3].x += 1e-9;
        assert_ne!(k, cache_key(&moved, &p));
        let mut flipped = c.clone();
        flipped.faces[0].swap(1, 2);
        assert_ne!(k, cache_key(&flipped, &p));
    }

    #[test]
    fn cache_round_trip_and_corruption() {
        let dir = tempfile::tempdir().unwrap();
        let c = cuboid(10.0, 10.0, 10.0);
        let p = StuffingParams::with_spacing(2.5);
        let key = cache_key(&c, &p);
        let m = template_tet_mesh_with(&c, &p, Some(dir.path())).unwrap();
        let path = cache_path(dir.path(), key);
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(decode(&bytes, key).as_ref(), Some(&m));
        assert_eq!(template_tet_mesh_with(&c, &p, Some(dir.path())).unwrap(), m);
        // Wrong key, truncation, an index out of range, a NaN: all rejected.
        assert!(decode(&bytes, key ^ 1).is_none());
        assert!(decode(&bytes[..bytes.len() - 1], key).is_none());
        let mut bad = bytes.clone();
        let last = bad.len() - 4;
        bad[last..].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(decode(&bad, key).is_none());
        let mut nan = bytes.clone();
        nan[HEADER..HEADER + 8].copy_from_slice(&f64::NAN.to_le_bytes());
        assert!(decode(&nan, key).is_none());
        // A huge count in a small file is refused before allocating.
        let mut huge = bytes.clone();
        huge[24..32].copy_from_slice(&(u64::MAX / 32).to_le_bytes());
        assert!(decode(&huge, key).is_none());
        // A corrupt cache file is ignored, rebuilt and rewritten.
        std::fs::write(&path, &bad).unwrap();
        assert_eq!(template_tet_mesh_with(&c, &p, Some(dir.path())).unwrap(), m);
        assert_eq!(std::fs::read(&path).unwrap(), bytes);
    }
}
