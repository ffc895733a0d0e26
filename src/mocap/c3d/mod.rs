//! C3D motion-capture trials (spec section 1: "C3D, any vendor; POINT:UNITS honoured"), read and
//! written by this module's own codec.
//!
//! Format reference: "The C3D File Format User Guide" (Motion Lab Systems, 2008), chapter 3 (the
//! 512-byte header), chapter 4 (the parameter section) and chapter 5 (3D point data).
//!
//! Only the point data matters here, a small part of the format, and trial files come from
//! anywhere: so the codec is this module's own, and the reader trusts nothing in the file. It
//! takes the Intel, DEC and MIPS processor types (byte order and float encoding), integer data
//! (times `POINT:SCALE`) and float data, analog samples interleaved with the points (skipped),
//! frame counts beyond the header's 16 bits, and `POINT:UNITS` m, cm, mm or in. Every count that
//! sizes an allocation or a loop is checked against the bytes present, so a corrupt file gives a
//! one-line error naming the file and the header word or parameter at fault, never a panic or an
//! allocation much larger than the file. Events, force plates and analog channels are not read.
//!
//! The writer makes the plainest file the format has (Intel, float data in mm, no analog data),
//! so that other readers need nothing unusual to take it; see [`write_c3d`].
//!
//! Label handling, in this order, for each trimmed `POINT:LABELS` entry (extensions beyond the
//! spec are marked):
//! 1. the subject's `[labels]` mapping, when it has the label;
//! 2. (extension) a Vicon-style `Subject:NAME` label: `[labels]` applied to `NAME`, else `NAME`
//!    itself when it is a spec marker name, else the label is kept whole;
//! 3. (extension) markers with an empty label cannot be named and are dropped;
//! 4. (extension) labels past the 255th are read from `POINT:LABELS2`, `LABELS3`, ...
//!
//! Two markers that end up with the same name are an error naming both.

mod format;
mod read;
mod write;

#[cfg(test)]
mod tests;

pub use self::write::MAX_WRITE_FRAMES;

use self::read::check_layout;
use crate::error::{Error, Result};
use crate::io::atomic::{read_bytes, write_bytes_atomic};
use crate::io::Units;
use crate::mocap::trajectories::{is_spec_marker_name, Trajectories};
use std::collections::BTreeMap;
use std::path::Path;

/// Read a C3D trial: marker positions in mm (from `POINT:UNITS`), frame rate from `POINT:RATE`
/// (checked against the header), labels mapped through `labels` (lab label -> spec name, the
/// subject's `[labels]` table) as described in the module documentation. Missing samples
/// (residual < 0 or non-finite coordinates, spec section 2) are `None`. Every error names `path`.
pub fn read_c3d(path: &Path, labels: &BTreeMap<String, String>) -> Result<Trajectories> {
    let bytes = read_bytes(path)?;
    read_c3d_bytes(&bytes, labels, path)
}

/// The `POINT:UNITS` of C3D bytes, `None` when the file does not pass [`read_c3d_bytes`]'s
/// header and parameter checks.
pub fn point_units(bytes: &[u8]) -> Option<Units> {
    check_layout(bytes).ok().map(|l| l.units)
}

/// [`read_c3d`] on bytes in memory; `label` is the file named in errors and kept as the
/// trajectories' `source`. Never panics, never allocates much more than `bytes.len()`.
pub fn read_c3d_bytes(
    bytes: &[u8],
    labels: &BTreeMap<String, String>,
    label: &Path,
) -> Result<Trajectories> {
    let fail = |msg: String| Error::input(label, msg);
    let layout = check_layout(bytes).map_err(fail)?;
    let mut names = Vec::new();
    let mut raw_of_name: BTreeMap<String, &str> = BTreeMap::new();
    let mut positions = Vec::new();
    for (m, raw) in layout.labels.iter().enumerate() {
        if raw.is_empty() {
            continue;
        }
        let name = canonical_label(raw, labels);
        if let Some(first) = raw_of_name.insert(name.clone(), raw) {
            return Err(fail(format!(
                "markers '{first}' and '{raw}' are both '{name}' after the [labels] mapping \
                 (POINT:LABELS); relabel one of them or fix [labels] in subject.toml"
            )));
        }
        let track = (0..layout.n_frames)
            .map(|f| layout.sample_mm(bytes, f, m))
            .collect();
        names.push(name);
        positions.push(track);
    }
    if names.is_empty() {
        return Err(fail("every marker label in POINT:LABELS is empty".into()));
    }
    Trajectories::new(f64::from(layout.rate), names, positions, label)
}

/// Write `traj` as a C3D file: Intel processor type, float data, `POINT:UNITS` "mm",
/// `POINT:RATE`, `POINT:SCALE` -1 (residual unit 1 mm), labels (continued in `POINT:LABELS2`, ...
/// beyond 255 markers), first frame 1, and frame counts beyond 65,535 the way c3d.org asks (see
/// `write::parameter_section`). A missing sample is written as (0, 0, 0) with residual -1, a
/// present one with residual 0 (user guide 5.2). Written atomically ([`write_bytes_atomic`]); the
/// same trajectories give the same bytes. Errors (a label or coordinate the format cannot hold,
/// more than [`MAX_WRITE_FRAMES`] frames) name `path` and leave it untouched.
pub fn write_c3d(path: &Path, traj: &Trajectories) -> Result<()> {
    let bytes = write::encode(traj).map_err(|msg| Error::input(path, msg))?;
    write_bytes_atomic(path, &bytes)
}

/// The canonical name of a raw (trimmed) C3D label; see the module documentation.
fn canonical_label(raw: &str, labels: &BTreeMap<String, String>) -> String {
    if let Some(name) = labels.get(raw) {
        return name.clone();
    }
    if let Some((_, bare)) = raw.rsplit_once(':') {
        if let Some(name) = labels.get(bare) {
            return name.clone();
        }
        if is_spec_marker_name(bare) {
            return bare.to_string();
        }
    }
    raw.to_string()
}
