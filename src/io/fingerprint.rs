//! Content fingerprints of a command's inputs, so that "up to date" means "made from these very
//! bytes" rather than "newer than": a folder replaced by another with preserved timestamps
//! (`cp -p`, `rsync -t`, an archive) is seen as changed.
//!
//! The hash is FNV-1a with 64 bits (Fowler, Noll & Vo; the offset basis and prime of the
//! reference at <http://www.isthe.com/chongo/tech/comp/fnv/>): not cryptographic, but a change
//! of any byte changes it, and it needs no dependency.

use crate::error::{Error, Result};
use std::io::Read;
use std::path::PathBuf;

/// FNV-1a, 64 bits, streamed.
#[derive(Clone, Copy, Debug)]
pub struct Fnv1a(u64);

impl Default for Fnv1a {
    fn default() -> Self {
        Fnv1a(0xcbf2_9ce4_8422_2325)
    }
}

impl Fnv1a {
    /// Add `bytes`.
    pub fn update(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 ^= u64::from(b);
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }

    /// The hash so far.
    pub fn finish(&self) -> u64 {
        self.0
    }
}

/// The fingerprint of `files` (their contents, each preceded by its length so that bytes cannot
/// move from one file to the next unnoticed, in the order given) and `options` (the text of the
/// settings that shape the outputs), as 16 hexadecimal digits. An unreadable file is an error
/// naming it.
pub fn inputs_fingerprint(files: &[PathBuf], options: &str) -> Result<String> {
    let mut h = Fnv1a::default();
    let mut buf = vec![0u8; 1 << 16];
    for f in files {
        let mut file = std::fs::File::open(f).map_err(|e| Error::io(f, e))?;
        let len = file.metadata().map_err(|e| Error::io(f, e))?.len();
        h.update(&len.to_le_bytes());
        loop {
            let n = file.read(&mut buf).map_err(|e| Error::io(f, e))?;
            if n == 0 {
                break;
            }
            h.update(&buf[..n]);
        }
    }
    h.update(&(options.len() as u64).to_le_bytes());
    h.update(options.as_bytes());
    Ok(format!("{:016x}", h.finish()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The reference's published test vectors.
    #[test]
    fn fnv1a_64_test_vectors() {
        let hash = |s: &str| {
            let mut h = Fnv1a::default();
            h.update(s.as_bytes());
            h.finish()
        };
        assert_eq!(hash(""), 0xcbf29ce484222325);
        assert_eq!(hash("a"), 0xaf63dc4c8601ec8c);
        assert_eq!(hash("foobar"), 0x85944171f73967e8);
    }

    #[test]
    fn fingerprint_sees_content_not_time() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a"), dir.path().join("b"));
        std::fs::write(&a, "abc").unwrap();
        std::fs::write(&b, "de").unwrap();
        let f = inputs_fingerprint(&[a.clone(), b.clone()], "x").unwrap();
        assert_eq!(f.len(), 16);
        assert_eq!(f, inputs_fingerprint(&[a.clone(), b.clone()], "x").unwrap());
        assert_ne!(f, inputs_fingerprint(&[a.clone(), b.clone()], "y").unwrap());
        // The same bytes split differently between the files.
        std::fs::write(&a, "ab").unwrap();
        std::fs::write(&b, "cde").unwrap();
        assert_ne!(f, inputs_fingerprint(&[a.clone(), b.clone()], "x").unwrap());
        let e = inputs_fingerprint(&[dir.path().join("none")], "x").unwrap_err();
        assert!(e.to_string().contains("none"), "{e}");
    }
}
