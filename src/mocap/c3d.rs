//! C3D motion-capture trials (spec section 1: "C3D, any vendor; POINT:UNITS honoured"), read and
//! written through the `c3dio` crate.
//!
//! Format reference: "The C3D File Format User Guide" (Motion Lab Systems, 2008), chapter 3 (the
//! 512-byte header), chapter 4 (the parameter section) and chapter 5 (3D point data).
//!
//! `c3dio` trusts the file: a mutated header can make it allocate gigabytes, underflow an index or
//! loop over garbage. So before any byte reaches it, [`read_c3d_bytes`] checks the header and walks
//! the parameter section itself with the same traversal `c3dio` uses, bounds-checked, and checks
//! every number `c3dio` sizes an allocation or a loop with (point and analog counts, the frame
//! count it derives from `POINT:FRAMES`, `TRIAL:ACTUAL_*_FIELD` and `POINT:LONG_FRAMES`) against
//! the bytes actually present. Only the point data is used: the event, force-plate,
//! manufacturer and segment groups are hidden from `c3dio`, whose parsers for them index the
//! header with counts from the file. The `c3dio` call is wrapped in `catch_unwind` as a last
//! resort.
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

use crate::error::{Error, Result};
use crate::geometry::Point;
use crate::io::atomic::{read_bytes, write_bytes_atomic};
use crate::io::Units;
use crate::mocap::trajectories::{is_spec_marker_name, Trajectories};
use c3dio::{C3d, MarkerPoint, Parameter};
use std::collections::BTreeMap;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

/// C3D block size (user guide chapter 2: the file is a sequence of 512-byte blocks).
const BLOCK: usize = 512;

/// Groups `c3dio` expects to exist when writing (it indexes them unconditionally) and inserts,
/// numbering them after the highest group id, when reading.
const REQUIRED_GROUPS: [&str; 8] = [
    "POINT",
    "ANALOG",
    "FORCE_PLATFORM",
    "EVENT",
    "EVENT_CONTEXT",
    "TRIAL",
    "MANUFACTURER",
    "SEG",
];

/// Groups of no use here whose `c3dio` parsers index the header and their own arrays with counts
/// taken from the file (`EVENT:USED` up to 32767 events read from a 512-byte header, platform
/// counts...). [`read_c3d_bytes`] hides them from `c3dio` by lower-casing their names in its copy
/// of the bytes (`c3dio` matches group names case-sensitively and then treats them as absent).
const HIDDEN_GROUPS: [&str; 5] = [
    "EVENT",
    "EVENT_CONTEXT",
    "FORCE_PLATFORM",
    "MANUFACTURER",
    "SEG",
];

/// Largest frame count [`write_c3d`] accepts: beyond 65,535 frames `POINT:FRAMES` is written as
/// a 32-bit float, exact up to 2^24.
pub const MAX_WRITE_FRAMES: usize = 1 << 24;

/// Frame counts a C3D header (16-bit words 4-5) and an integer `POINT:FRAMES` can hold.
const MAX_SHORT_FRAMES: usize = 65_535;

/// Largest marker count [`write_c3d`] accepts: `c3dio` writes `POINT:LABELS` with u8 dimensions.
pub const MAX_WRITE_MARKERS: usize = 255;

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
    let c3d = parse_with_c3dio(bytes, &layout).map_err(fail)?;
    let points = &c3d.points;
    if points.cols() != layout.n_points || points.rows() != layout.n_frames {
        return Err(fail(format!(
            "c3dio read {} frames of {} markers where the header and parameters say {} of {}",
            points.rows(),
            points.cols(),
            layout.n_frames,
            layout.n_points
        )));
    }
    let to_mm = layout.units.to_mm();
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
            .map(|f| points.get(f, m).and_then(|p| sample_mm(p, to_mm)))
            .collect();
        names.push(name);
        positions.push(track);
    }
    if names.is_empty() {
        return Err(fail("every marker label in POINT:LABELS is empty".into()));
    }
    Trajectories::new(f64::from(layout.rate), names, positions, label)
}

/// Write `traj` as a C3D file through `c3dio`: float data, `POINT:UNITS` "mm", `POINT:RATE`,
/// `POINT:SCALE` -1 (residual unit 1 mm), `POINT:DATA_START`, first frame 1; a missing sample is
/// written as (0, 0, 0) with residual -1, a present one with residual 0 (user guide 5.2).
///
/// `c3dio` writes to a path, not atomically, and departs from the user guide in a few places
/// (see `standardise` below). So it writes a hidden sibling file that is read back,
/// standardised and then written to `path` with [`write_bytes_atomic`]. The output is
/// deterministic: the same trajectories give the same bytes. It reads back the same through
/// `c3dio`, [`read_c3d`] and ezc3d 1.7 (checked by hand).
pub fn write_c3d(path: &Path, traj: &Trajectories) -> Result<()> {
    let fail = |msg: String| Error::input(path, msg);
    check_writable(traj).map_err(fail)?;
    let c3d = build_c3dio(traj).map_err(fail)?;
    let tmp = c3dio_temp_path(path);
    let written = catch_unwind(AssertUnwindSafe(|| c3d.write_path(tmp.clone()).map(|_| ())));
    let bytes = match written {
        Ok(Ok(())) => std::fs::read(&tmp).map_err(|e| Error::io(&tmp, e)),
        Ok(Err(e)) => Err(fail(format!("c3dio could not write the file: {e:?}"))),
        Err(_) => Err(fail("c3dio panicked while writing the file".into())),
    };
    let _ = std::fs::remove_file(&tmp);
    let bytes = standardise(&bytes?, traj).map_err(fail)?;
    write_bytes_atomic(path, &bytes)
}

// ---------------------------------------------------------------------------------------------
// Reading

/// What the header and parameter checks established, in the terms `c3dio` will use.
#[derive(Debug)]
struct Layout {
    /// Parameter block index (header byte 1); always 2 here.
    data_start: usize,
    n_points: usize,
    /// Frames `c3dio` will read.
    n_frames: usize,
    units: Units,
    rate: f32,
    /// One per point, trimmed, in column order.
    labels: Vec<String>,
    /// File offsets of the names of the groups in [`HIDDEN_GROUPS`].
    hidden_names: Vec<(usize, usize)>,
    /// File offsets of the data of `TRIAL:ACTUAL_START_FIELD` and `ACTUAL_END_FIELD` when both
    /// are present, and the end field's words that make `c3dio` count `n_frames` from a start
    /// field of [1, 0].
    trial_fields: Option<(usize, usize, [u16; 2])>,
    proc: Proc,
}

/// Most frames `c3dio` can count from `TRIAL:ACTUAL_*_FIELD` (low + 65,535 x high, high <= 1).
const C3DIO_TRIAL_FRAMES: u128 = 2 * 65_535;

/// The processor type of user guide 4.1 (parameter block byte 4 = 83 + type): byte order and
/// float encoding of every number in the file.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Proc {
    Intel,
    Dec,
    Mips,
}

impl Proc {
    fn from_byte(b: u8) -> Option<Proc> {
        match b {
            0x54 => Some(Proc::Intel),
            0x55 => Some(Proc::Dec),
            0x56 => Some(Proc::Mips),
            _ => None,
        }
    }

    fn u16(self, b: [u8; 2]) -> u16 {
        match self {
            Proc::Mips => u16::from_be_bytes(b),
            _ => u16::from_le_bytes(b),
        }
    }

    fn i16(self, b: [u8; 2]) -> i16 {
        self.u16(b) as i16
    }

    /// As `c3dio` decodes it (DEC: word-swapped, exponent biased by 2 i.e. one step of the high
    /// byte), so that the checks here agree with what `c3dio` will see.
    fn f32(self, b: [u8; 4]) -> f32 {
        match self {
            Proc::Intel => f32::from_le_bytes(b),
            Proc::Mips => f32::from_be_bytes(b),
            Proc::Dec => {
                let hi = if b[1] == 0 { 0 } else { b[1] - 1 };
                f32::from_le_bytes([b[2], b[3], b[0], hi])
            }
        }
    }
}

/// One parameter of the parameter section (user guide 4.3), as `c3dio` sees it.
#[derive(Debug)]
struct Param {
    group: String,
    name: String,
    /// -1 char, 1 byte, 2 integer, 4 float.
    kind: i8,
    /// Offset of `data` in the parameter section.
    at: usize,
    /// Dimensions after `c3dio`'s normalisation (zeros dropped, ones dropped for non-char,
    /// `[1]` when nothing is left).
    dims: Vec<usize>,
    data: Vec<u8>,
}

impl Param {
    fn ints(&self, p: Proc) -> Option<Vec<i16>> {
        (self.kind == 2).then(|| {
            self.data
                .chunks_exact(2)
                .map(|c| p.i16([c[0], c[1]]))
                .collect()
        })
    }

    fn floats(&self, p: Proc) -> Option<Vec<f32>> {
        (self.kind == 4).then(|| {
            self.data
                .chunks_exact(4)
                .map(|c| p.f32([c[0], c[1], c[2], c[3]]))
                .collect()
        })
    }

    /// The character data as strings of `dims[0]` characters (Latin-1, as `c3dio` reads it),
    /// trimmed of blanks and NULs.
    fn strings(&self) -> Option<Vec<String>> {
        if self.kind != -1 || self.dims.is_empty() || self.dims.len() > 2 {
            return None;
        }
        let width = self.dims[0].max(1);
        Some(
            self.data
                .chunks(width)
                .map(|c| {
                    let s: String = c.iter().map(|&b| b as char).collect();
                    s.trim_matches(|ch: char| ch.is_whitespace() || ch == '\0')
                        .to_string()
                })
                .collect(),
        )
    }

    /// A single number, integer or float, the way `c3dio` reads counts (`as u16`/`as usize`).
    fn count(&self, p: Proc) -> Option<usize> {
        match self.kind {
            2 => self.ints(p)?.first().map(|&v| v as u16 as usize),
            4 => self.floats(p)?.first().map(|&v| v as usize),
            _ => None,
        }
    }
}

/// The parameters of a file, and its group records as (id, name, offset of the name in the
/// parameter section).
struct Params {
    list: Vec<Param>,
    groups: Vec<(i8, String, usize)>,
}

impl Params {
    /// The last parameter `GROUP:NAME` (`c3dio` keeps the last of duplicates).
    fn get(&self, group: &str, name: &str) -> Option<&Param> {
        self.list
            .iter()
            .rev()
            .find(|p| p.group == group && p.name == name)
    }
}

/// Walk the parameter section exactly as `c3dio` 0.8 does (start at byte 4; an entry with
/// group id 0 or the end of the section stops; a negative id is a group, a positive one a
/// parameter; the next entry is `offset` bytes after the offset word), with every read
/// bounds-checked, and reject what would make `c3dio` panic (`i8::MIN` ids and name lengths,
/// group ids that overflow when it adds its required groups).
fn walk_parameters(section: &[u8], proc: Proc) -> std::result::Result<Params, String> {
    let bad = |what: &str, at: usize| {
        format!(
            "parameter section corrupt: {what} at byte {} of the file",
            BLOCK + at
        )
    };
    let slice = |from: usize, len: usize, what: &str| {
        section
            .get(from..from.saturating_add(len))
            .ok_or_else(|| bad(what, from))
    };
    let mut groups: Vec<(i8, String, usize)> = Vec::new();
    let mut raw: Vec<(i8, Param)> = Vec::new();
    let mut index = 4;
    while index + 1 < section.len() {
        let id = section[index + 1] as i8;
        if id == 0 {
            break;
        }
        let name_len = section[index] as i8;
        if name_len == i8::MIN || id == i8::MIN {
            return Err(bad("entry header out of range", index));
        }
        let mut i = index + 2;
        let name: String = slice(i, name_len.unsigned_abs() as usize, "name")?
            .iter()
            .map(|&b| b as char)
            .collect();
        i += name_len.unsigned_abs() as usize;
        let off = slice(i, 2, "offset")?;
        let next = i + proc.u16([off[0], off[1]]) as usize;
        i += 2;
        if id < 0 {
            let desc_len = *slice(i, 1, "description length")?.first().unwrap_or(&0) as usize;
            slice(i + 1, desc_len, "description")?;
            groups.push((id.abs(), name, index + 2));
        } else {
            let kind = *slice(i, 1, "type")?.first().unwrap_or(&0) as i8;
            let size: usize = match kind {
                -1 | 1 => 1,
                2 => 2,
                4 => 4,
                _ => return Err(bad(&format!("parameter {name} has type {kind}"), i)),
            };
            i += 1;
            let ndims = *slice(i, 1, "dimension count")?.first().unwrap_or(&0) as usize;
            i += 1;
            let mut dims: Vec<usize> = slice(i, ndims, "dimensions")?
                .iter()
                .map(|&d| d as usize)
                .filter(|&d| d != 0 && (kind == -1 || d != 1))
                .collect();
            if dims.is_empty() {
                dims.push(1);
            }
            i += ndims;
            // Bounded by the section length before multiplying on: 255 dimensions of 255
            // would overflow (c3dio's own product panics there).
            let len = dims
                .iter()
                .try_fold(size, |acc, &d| {
                    acc.checked_mul(d).filter(|&l| l <= section.len())
                })
                .ok_or_else(|| bad(&format!("parameter {name} is larger than the section"), i))?;
            let data = slice(i, len, "data")?.to_vec();
            i += len;
            let desc_len = *slice(i, 1, "description length")?.first().unwrap_or(&0) as usize;
            slice(i + 1, desc_len, "description")?;
            let param = Param {
                group: String::new(),
                name: name.to_ascii_uppercase(),
                kind,
                at: i - len,
                dims,
                data,
            };
            raw.push((id, param));
        }
        index = next;
    }
    // c3dio numbers missing required groups after the highest id with i8 arithmetic; the
    // groups hidden from it (see `parse_with_c3dio`) count as missing.
    let max_id = groups.iter().map(|g| g.0).max().unwrap_or(0) as i32;
    let missing = REQUIRED_GROUPS
        .iter()
        .filter(|r| HIDDEN_GROUPS.contains(r) || !groups.iter().any(|g| g.1 == **r))
        .count() as i32;
    if max_id + missing > i8::MAX as i32 {
        return Err(format!(
            "parameter section corrupt: group id {max_id} too large"
        ));
    }
    let list = raw
        .into_iter()
        .map(|(id, mut p)| {
            p.group = groups
                .iter()
                .rev()
                .find(|g| g.0 == id)
                .map_or_else(|| id.to_string(), |g| g.1.clone());
            p
        })
        .collect();
    Ok(Params { list, groups })
}

/// Check the header (user guide 3.1) and the parameters `c3dio` relies on, and work out the
/// frame count it will read; every message names the header word or parameter at fault.
fn check_layout(bytes: &[u8]) -> std::result::Result<Layout, String> {
    let len = bytes.len();
    if len < 2 * BLOCK {
        return Err(format!(
            "not a C3D file: {len} bytes, less than a header and a parameter block (1024)"
        ));
    }
    if bytes[1] != 0x50 {
        return Err(format!(
            "not a C3D file: header byte 2 is {:#04x}, expected 0x50",
            bytes[1]
        ));
    }
    if bytes[0] != 2 {
        return Err(format!(
            "header byte 1 puts the parameter section at block {}; only block 2 (every current \
             writer's choice) is supported",
            bytes[0]
        ));
    }
    let proc = Proc::from_byte(bytes[BLOCK + 3]).ok_or_else(|| {
        format!(
            "unknown processor type {} in the parameter section (expected 84, 85 or 86)",
            bytes[BLOCK + 3]
        )
    })?;
    let word = |w: usize| proc.u16([bytes[2 * w - 2], bytes[2 * w - 1]]);
    let float = |w: usize| {
        let o = 2 * w - 2;
        proc.f32([bytes[o], bytes[o + 1], bytes[o + 2], bytes[o + 3]])
    };
    let n_points = word(2) as usize;
    let analog_per_frame = word(3) as usize;
    let (first, last) = (word(4), word(5));
    let scale = float(7);
    let data_start = word(9) as usize;
    let analog_per_channel = word(10) as usize;
    let rate = float(11);

    if data_start < 3 || BLOCK * (data_start - 1) > len {
        return Err(format!(
            "data start block {data_start} (header word 9) is not between 3 and the end of the \
             file ({} blocks)",
            len.div_ceil(BLOCK)
        ));
    }
    let data_len = len - BLOCK * (data_start - 1);
    if n_points == 0 {
        return Err("the trial has no markers (header word 2 is 0)".into());
    }
    if first > last {
        return Err(format!(
            "header frame range {first}..{last} (words 4 and 5) is reversed"
        ));
    }
    if !scale.is_finite() {
        return Err(format!("POINT scale factor (header word 7) is {scale}"));
    }
    let float_format = scale <= 0.0;
    if !float_format && scale == 0.0 {
        return Err("POINT scale factor (header word 7) is 0".into());
    }
    if !(rate.is_finite() && rate > 0.0) {
        return Err(format!(
            "frame rate (header word 11) is {rate}, not a positive number"
        ));
    }
    let word_bytes = if float_format { 4 } else { 2 };
    let bytes_per_frame = (4 * n_points + analog_per_frame) as u128 * word_bytes;
    let header_frames = (last - first) as u128 + 1;
    if header_frames * bytes_per_frame > data_len as u128 {
        return Err(format!(
            "file truncated: header frames {first}..{last} of {n_points} markers need {} bytes of \
             data, {data_len} follow the data start",
            header_frames * bytes_per_frame
        ));
    }

    let params = walk_parameters(&bytes[BLOCK..BLOCK * (data_start - 1)], proc)?;
    let p = |g: &str, n: &str| params.get(g, n);

    // POINT:USED decides whether c3dio reads the labels at all.
    let used = p("POINT", "USED")
        .and_then(|u| u.count(proc))
        .ok_or("POINT:USED is missing or not a number")?;
    if used != n_points {
        return Err(format!(
            "POINT:USED is {used} but the header (word 2) says {n_points} markers"
        ));
    }
    let mut labels = p("POINT", "LABELS")
        .and_then(Param::strings)
        .ok_or("POINT:LABELS is missing or not text")?;
    for k in 2.. {
        if labels.len() >= n_points {
            break;
        }
        match p("POINT", &format!("LABELS{k}")).and_then(Param::strings) {
            Some(more) => labels.extend(more),
            None => break,
        }
    }
    if labels.len() < n_points {
        return Err(format!(
            "POINT:LABELS names {} markers but the file has {n_points}",
            labels.len()
        ));
    }
    labels.truncate(n_points);
    if let Some(d) = p("POINT", "DESCRIPTIONS") {
        if d.strings().is_none() {
            return Err("POINT:DESCRIPTIONS is not text".into());
        }
    }
    let units_text = p("POINT", "UNITS")
        .filter(|u| u.kind == -1)
        .and_then(|u| u.strings())
        .map(|s| s.concat())
        .ok_or("POINT:UNITS is missing (expected mm, cm or m)")?;
    let units: Units = units_text
        .parse()
        .map_err(|_| format!("POINT:UNITS is '{units_text}' (expected mm, cm or m)"))?;
    if let Some(r) = p("POINT", "RATE") {
        match r.floats(proc).as_deref() {
            Some([v]) if *v == rate => {}
            Some([v]) => {
                return Err(format!(
                    "POINT:RATE ({v} Hz) disagrees with the header frame rate ({rate} Hz)"
                ))
            }
            _ => return Err("POINT:RATE is not a single float".into()),
        }
    }
    if let Some(s) = p("POINT", "SCALE") {
        match s.floats(proc).as_deref() {
            Some([v]) if v.abs() == scale.abs() => {}
            _ => {
                return Err(format!(
                    "POINT:SCALE disagrees with the header scale factor ({scale})"
                ))
            }
        }
    }

    // The frame count (user guide 3.1 and 4.4; c3d.org, "The C3D frame count"): POINT:FRAMES
    // (an integer up to 65,535, a float beyond), replaced by TRIAL:ACTUAL_END_FIELD -
    // ACTUAL_START_FIELD + 1 when both are present (each a 32-bit frame number stored as two
    // 16-bit words, low word first), and POINT:LONG_FRAMES (a float) when it is larger. The
    // header's 16-bit frame range (words 4-5) cannot hold more than 65,535 frames and is not used.
    let mut n_frames = p("POINT", "FRAMES")
        .and_then(|f| f.count(proc))
        .unwrap_or(0) as u128;
    let field = |name: &str| -> std::result::Result<Option<(u128, usize)>, String> {
        let Some(f) = p("TRIAL", name) else {
            return Ok(None);
        };
        match f.ints(proc) {
            Some(v) if f.dims.len() == 1 && v.len() == 2 => {
                let frame = v[0] as u16 as u128 + ((v[1] as u16 as u128) << 16);
                Ok(Some((frame, BLOCK + f.at)))
            }
            Some(_) if f.dims.len() == 1 => Ok(None),
            _ => Err(format!("TRIAL:{name} is not a list of integers")),
        }
    };
    let end = field("ACTUAL_END_FIELD")?;
    let start = field("ACTUAL_START_FIELD")?;
    let mut trial_fields = None;
    if let (Some((s, s_at)), Some((e, e_at))) = (start, end) {
        if e < s {
            return Err(format!(
                "TRIAL:ACTUAL_END_FIELD ({e}) is before TRIAL:ACTUAL_START_FIELD ({s})"
            ));
        }
        n_frames = e - s + 1;
        trial_fields = Some((s_at, e_at));
    }
    // c3dio reads these two fields as low + 65,535 x high in 16-bit arithmetic (one frame short
    // past 65,535, wrapping past 131,070); `parse_with_c3dio` rewrites them in its copy so that
    // c3dio's formula gives the count found here, which it can for up to 131,070 frames.
    let c3dio_trial_frames = trial_fields.map(|_| n_frames.min(C3DIO_TRIAL_FRAMES));
    let mut c3dio_frames = c3dio_trial_frames.unwrap_or(n_frames);
    if let Some(l) = p("POINT", "LONG_FRAMES") {
        let long = l.count(proc).unwrap_or(0) as u128;
        n_frames = n_frames.max(long);
        c3dio_frames = c3dio_frames.max(long);
    }
    if c3dio_frames != n_frames {
        return Err(format!(
            "TRIAL:ACTUAL_START_FIELD and ACTUAL_END_FIELD give {n_frames} frames; more than \
             {C3DIO_TRIAL_FRAMES} are read only with POINT:FRAMES or POINT:LONG_FRAMES as a float"
        ));
    }
    if n_frames == 0 {
        return Err("the trial has no frames (POINT:FRAMES is 0 or missing)".into());
    }
    if n_frames * bytes_per_frame > data_len as u128 {
        return Err(format!(
            "file truncated: {n_frames} frames (POINT:FRAMES) of {n_points} markers need {} bytes \
             of data, {data_len} follow the data start",
            n_frames * bytes_per_frame
        ));
    }

    // c3dio sizes its analog grid by ANALOG:USED before checking it against the header.
    if let Some(a) = p("ANALOG", "USED") {
        let analog_used = match a.ints(proc).as_deref() {
            Some([v]) => *v as u16 as usize,
            _ => return Err("ANALOG:USED is not a single integer".into()),
        };
        if analog_used != 0 && analog_used * analog_per_channel != analog_per_frame {
            return Err(format!(
                "ANALOG:USED ({analog_used}) times the analog samples per frame (header word 10, \
                 {analog_per_channel}) is not the header's analog count (word 3, \
                 {analog_per_frame})"
            ));
        }
    }
    // c3dio reserves EVENT:USED events up front; a negative count is a huge reservation.
    if let Some(e) = p("EVENT", "USED") {
        if e.ints(proc)
            .is_some_and(|v| v.first().is_some_and(|&n| n < 0))
        {
            return Err("EVENT:USED is negative".into());
        }
    }

    let hidden_names = params
        .groups
        .iter()
        .filter(|g| HIDDEN_GROUPS.contains(&g.1.as_str()))
        .map(|g| (BLOCK + g.2, g.1.len()))
        .collect();
    Ok(Layout {
        hidden_names,
        trial_fields: trial_fields.map(|(s_at, e_at)| {
            let n = n_frames.min(C3DIO_TRIAL_FRAMES) as u32;
            let end = if n > 65_535 { [n - 65_535, 1] } else { [n, 0] };
            (s_at, e_at, end.map(|w| w as u16))
        }),
        proc,
        data_start,
        n_points,
        n_frames: n_frames as usize,
        units,
        rate,
        labels,
    })
}

/// Panics caught around `c3dio` (tests assert that the checks leave none to catch).
#[cfg(test)]
static C3DIO_PANICS: AtomicUsize = AtomicUsize::new(0);

/// Hand the checked bytes to `c3dio`, in a copy
/// - padded with zeros to whole blocks (it insists on at least one whole data block, which
///   short files written without padding lack; the frame count was checked against the unpadded
///   length, so padding never adds frames);
/// - with the groups of [`HIDDEN_GROUPS`] renamed to lower case and the header's event-label
///   flag (word 150) cleared, so that its event, force-plate, manufacturer and segment parsers
///   see nothing (their data is not used here);
/// - with `TRIAL:ACTUAL_START_FIELD` and `ACTUAL_END_FIELD` rewritten (see `Layout`) so that
///   `c3dio` counts the frames found by [`check_layout`].
fn parse_with_c3dio(bytes: &[u8], layout: &Layout) -> std::result::Result<C3d, String> {
    let want = bytes.len().div_ceil(BLOCK).max(layout.data_start) * BLOCK;
    let mut buf = Vec::with_capacity(want);
    buf.extend_from_slice(bytes);
    buf.resize(want, 0);
    for &(at, len) in &layout.hidden_names {
        buf[at..at + len].make_ascii_lowercase();
    }
    buf[298..300].fill(0);
    if let Some((s_at, e_at, end)) = layout.trial_fields {
        let word = |w: u16| match layout.proc {
            Proc::Mips => w.to_be_bytes(),
            _ => w.to_le_bytes(),
        };
        for (at, words) in [(s_at, [1, 0]), (e_at, end)] {
            buf[at..at + 2].copy_from_slice(&word(words[0]));
            buf[at + 2..at + 4].copy_from_slice(&word(words[1]));
        }
    }
    // c3dio's errors carry whole parameters; keep the message to one short line.
    let parse = || C3d::from_bytes(&buf).map_err(|e| format!("{e:?}"));
    match catch_unwind(AssertUnwindSafe(parse)) {
        Ok(Ok(c3d)) => Ok(c3d),
        Ok(Err(e)) => {
            let short: String = e.chars().take(160).collect();
            let more = if short.len() < e.len() { "..." } else { "" };
            Err(format!("unreadable C3D file (c3dio: {short}{more})"))
        }
        Err(_) => {
            #[cfg(test)]
            C3DIO_PANICS.fetch_add(1, Ordering::Relaxed);
            Err("unreadable C3D file (c3dio panicked)".into())
        }
    }
}

/// A `c3dio` sample as a point in mm, `None` when missing: a negative residual (for a zero
/// scale factor `c3dio` turns it into -0.0, hence the sign test) or non-finite coordinates.
fn sample_mm(p: &MarkerPoint, to_mm: f64) -> Option<Point> {
    if p.residual.is_sign_negative() || p.point.iter().any(|c| !c.is_finite()) {
        return None;
    }
    let [x, y, z] = p.point.map(|c| f64::from(c) * to_mm);
    Some(Point::new(x, y, z))
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

// ---------------------------------------------------------------------------------------------
// Writing

/// What `c3dio`'s writer can represent faithfully; a message naming the marker otherwise.
fn check_writable(traj: &Trajectories) -> std::result::Result<(), String> {
    let n = traj.labels.len();
    let frames = traj.n_frames();
    if n == 0 || n > MAX_WRITE_MARKERS {
        return Err(format!(
            "cannot write {n} markers (1 to {MAX_WRITE_MARKERS} fit in POINT:LABELS)"
        ));
    }
    if traj.positions.len() != n {
        return Err(format!("{n} labels for {} tracks", traj.positions.len()));
    }
    check_frame_count(frames)?;
    let rate = traj.frame_rate as f32;
    if !(rate.is_finite() && rate > 0.0) {
        return Err(format!(
            "frame rate {} Hz cannot be written",
            traj.frame_rate
        ));
    }
    let mut seen = BTreeMap::new();
    for (label, track) in traj.labels.iter().zip(&traj.positions) {
        if label.is_empty()
            || label.len() > 255
            || !label.bytes().all(|b| b.is_ascii_graphic() || b == b' ')
            || label.trim() != label
        {
            return Err(format!(
                "marker label '{label}' cannot be written (1 to 255 printable ASCII characters, \
                 no leading or trailing blanks)"
            ));
        }
        if seen.insert(label.as_str(), ()).is_some() {
            return Err(format!("marker label '{label}' occurs twice"));
        }
        if track.len() != frames {
            return Err(format!(
                "marker '{label}' has {} frames, the others {frames}",
                track.len()
            ));
        }
        for (f, p) in track.iter().enumerate() {
            if let Some(p) = p {
                if p.iter().any(|c| !(*c as f32).is_finite()) {
                    return Err(format!(
                        "marker '{label}' frame {f}: coordinates {:?} do not fit a 32-bit float",
                        p.coords.as_slice()
                    ));
                }
            }
        }
    }
    Ok(())
}

/// A frame count [`write_c3d`] can write exactly (1 to [`MAX_WRITE_FRAMES`]).
fn check_frame_count(frames: usize) -> std::result::Result<(), String> {
    if frames == 0 || frames > MAX_WRITE_FRAMES {
        return Err(format!(
            "cannot write {frames} frames (1 to {MAX_WRITE_FRAMES} are exact in POINT:FRAMES)"
        ));
    }
    Ok(())
}

/// The `c3dio` value to write: groups `c3dio` indexes, points, and the POINT parameters it does
/// not write itself (RATE, SCALE, a DATA_START placeholder patched later).
fn build_c3dio(traj: &Trajectories) -> std::result::Result<C3d, String> {
    let mut c3d = C3d::new();
    for g in REQUIRED_GROUPS {
        c3d.parameters.insert_group(g, String::new());
    }
    let n = traj.labels.len();
    let points = &mut c3d.points;
    points.labels = traj.labels.clone();
    points.descriptions = vec![String::new(); n];
    points.units = ['m', 'm', ' ', ' '];
    points.frame_rate = traj.frame_rate as f32;
    points.scale_factor = 1.0;
    points.first_frame = 1;
    points.last_frame = traj.n_frames().min(MAX_SHORT_FRAMES) as u16;
    for f in 0..traj.n_frames() {
        let row = traj
            .positions
            .iter()
            .map(|t| match t[f] {
                Some(p) => MarkerPoint {
                    point: [p.x as f32, p.y as f32, p.z as f32],
                    residual: 0.0,
                    cameras: [false; 7],
                },
                None => MarkerPoint {
                    point: [0.0; 3],
                    residual: -1.0,
                    cameras: [false; 7],
                },
            })
            .collect();
        points.points.push_row(row);
    }
    c3d.parameters
        .insert("POINT", "RATE", Parameter::float(traj.frame_rate as f32));
    c3d.parameters
        .insert("POINT", "SCALE", Parameter::float(-1.0));
    c3d.parameters
        .insert("POINT", "DATA_START", Parameter::integer(0));
    Ok(c3d)
}

/// Turn `c3dio`'s output into a file that follows the user guide, keeping its header, parameter
/// values and point data:
/// - the parameter section is re-serialised (4.2, 4.3): `c3dio` omits the description-length
///   byte of group records, which readers that check record boundaries (ezc3d) reject, and
///   orders groups and parameters by hash, so its bytes change from run to run. Here groups come
///   in [`REQUIRED_GROUPS`] order, parameters sorted by group and name, descriptions empty, and a
///   zero record ends the section;
/// - `POINT:FRAMES` becomes an integer (4.4; `c3dio` writes a float), `POINT:DATA_START` and the
///   parameter block count (section byte 3) get their values;
/// - beyond 65,535 frames, as c3d.org's "Maintaining C3D frame count compatibility" asks:
///   `POINT:FRAMES` stays a float, the header's frame range is 1..65,535, and
///   `POINT:LONG_FRAMES` (float) and `TRIAL:ACTUAL_START_FIELD` / `ACTUAL_END_FIELD` (two 16-bit
///   words each, low first) are added for readers that take the count from those (the Python
///   `c3d` package, Vicon's software);
/// - the residual word of every sample is -1.0 when missing and 0.0 when present (5.2; `c3dio`
///   writes 255.0 for -1);
/// - the data is padded with zeros to whole blocks (chapter 2).
fn standardise(bytes: &[u8], traj: &Trajectories) -> std::result::Result<Vec<u8>, String> {
    let malformed = || "c3dio wrote a malformed file".to_string();
    if bytes.len() < 2 * BLOCK {
        return Err(malformed());
    }
    let old_start = u16::from_le_bytes([bytes[16], bytes[17]]) as usize;
    if old_start < 3 || BLOCK * (old_start - 1) > bytes.len() {
        return Err(malformed());
    }
    let params = walk_parameters(&bytes[BLOCK..BLOCK * (old_start - 1)], Proc::Intel)?;
    let (n, frames) = (traj.labels.len(), traj.n_frames());
    let data = bytes
        .get(BLOCK * (old_start - 1)..BLOCK * (old_start - 1) + 16 * n * frames)
        .ok_or_else(malformed)?;

    let group_index = |g: &str| REQUIRED_GROUPS.iter().position(|r| *r == g);
    let mut list: Vec<&Param> = params
        .list
        .iter()
        .filter(|p| group_index(&p.group).is_some())
        .collect();

    let mut sec = vec![1u8, 0x50, 0, 0x54];
    for (i, g) in REQUIRED_GROUPS.iter().enumerate() {
        sec.extend([g.len() as u8, (-(i as i8 + 1)) as u8]);
        sec.extend(g.as_bytes());
        sec.extend(3u16.to_le_bytes());
        sec.push(0);
    }
    let long = frames > MAX_SHORT_FRAMES;
    let frames_value = if long {
        (frames as f32).to_le_bytes().to_vec()
    } else {
        (frames as u16).to_le_bytes().to_vec()
    };
    let words = |n: usize| -> Vec<u8> {
        let n = n as u32;
        [(n & 0xffff) as u16, (n >> 16) as u16]
            .iter()
            .flat_map(|w| w.to_le_bytes())
            .collect()
    };
    let extra = |group: &str, name: &str, kind: i8, data: Vec<u8>| Param {
        group: group.into(),
        name: name.into(),
        kind,
        at: 0,
        dims: if kind == 2 { vec![2] } else { vec![1] },
        data,
    };
    let long_params = if long {
        vec![
            extra(
                "POINT",
                "LONG_FRAMES",
                4,
                (frames as f32).to_le_bytes().to_vec(),
            ),
            extra("TRIAL", "ACTUAL_START_FIELD", 2, words(1)),
            extra("TRIAL", "ACTUAL_END_FIELD", 2, words(frames)),
        ]
    } else {
        Vec::new()
    };
    list.extend(long_params.iter());
    list.sort_by_key(|p| (group_index(&p.group), p.name.clone()));
    let mut data_start_at = None;
    for p in list {
        let (kind, dims, value): (i8, Vec<usize>, &[u8]) = match (p.group.as_str(), p.name.as_str())
        {
            ("POINT", "FRAMES") => (if long { 4 } else { 2 }, vec![1], &frames_value),
            _ => (p.kind, p.dims.clone(), &p.data),
        };
        if p.name.len() > 127 || dims.len() > 255 || dims.iter().any(|&d| d > 255) {
            return Err(format!(
                "parameter {}:{} cannot be written",
                p.group, p.name
            ));
        }
        let id = group_index(&p.group).unwrap_or(0) as u8 + 1;
        sec.extend([p.name.len() as u8, id]);
        sec.extend(p.name.as_bytes());
        let offset = 2 + 1 + 1 + dims.len() + value.len() + 1;
        sec.extend(
            u16::try_from(offset)
                .map_err(|_| malformed())?
                .to_le_bytes(),
        );
        sec.extend([kind as u8, dims.len() as u8]);
        sec.extend(dims.iter().map(|&d| d as u8));
        if p.group == "POINT" && p.name == "DATA_START" {
            data_start_at = Some(sec.len());
        }
        sec.extend(value);
        sec.push(0);
    }
    sec.extend([0, 0]);
    sec.resize(sec.len().div_ceil(BLOCK) * BLOCK, 0);
    let blocks = sec.len() / BLOCK;
    let data_start = 2 + blocks;
    if blocks > u8::MAX as usize || data_start > i16::MAX as usize {
        return Err("the parameter section is too large".into());
    }
    sec[2] = blocks as u8;
    let at = data_start_at.ok_or_else(malformed)?;
    sec[at..at + 2].copy_from_slice(&(data_start as i16).to_le_bytes());

    let mut out = Vec::with_capacity(BLOCK * (data_start - 1) + data.len() + BLOCK);
    out.extend_from_slice(&bytes[..BLOCK]);
    out[16..18].copy_from_slice(&(data_start as u16).to_le_bytes());
    out.extend(sec);
    let data_at = out.len();
    out.extend_from_slice(data);
    for f in 0..frames {
        for (m, track) in traj.positions.iter().enumerate() {
            let at = data_at + 16 * (f * n + m) + 12;
            let residual: f32 = if track[f].is_some() { 0.0 } else { -1.0 };
            out[at..at + 4].copy_from_slice(&residual.to_le_bytes());
        }
    }
    out.resize(out.len().div_ceil(BLOCK) * BLOCK, 0);
    Ok(out)
}

/// A hidden sibling of `path` with the `.c3d` extension `c3dio` insists on, unique per process
/// and call so that parallel writers do not collide.
fn c3dio_temp_path(path: &Path) -> PathBuf {
    static COUNTER: AtomicUsize = AtomicUsize::new(0);
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "trial".into());
    path.with_file_name(format!(
        ".{name}.{}.{}.c3dio.c3d",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use proptest::sample::Index;
    use std::sync::OnceLock;

    fn no_map() -> BTreeMap<String, String> {
        BTreeMap::new()
    }

    /// Smooth, distinct tracks with gaps: marker m misses frames where (f + m) % 7 == 3, the last
    /// marker is missing in every frame of the first ten.
    fn sample(labels: &[&str], frames: usize) -> Trajectories {
        let positions = (0..labels.len())
            .map(|m| {
                (0..frames)
                    .map(|f| {
                        let t = f as f64 * 0.1 + m as f64;
                        let gap = (f + m) % 7 == 3 || (m + 1 == labels.len() && f < 10);
                        (!gap).then(|| {
                            Point::new(
                                250.0 * t.sin() - 12.345,
                                -700.0 + 30.0 * t.cos(),
                                1000.0 + 0.001 * f as f64,
                            )
                        })
                    })
                    .collect()
            })
            .collect();
        Trajectories::new(
            120.0,
            labels.iter().map(|s| s.to_string()).collect(),
            positions,
            "mem.c3d",
        )
        .unwrap()
    }

    fn assert_same_within_f32(a: &Trajectories, b: &Trajectories) {
        assert_eq!(a.labels, b.labels);
        assert_eq!(a.n_frames(), b.n_frames());
        for (ta, tb) in a.positions.iter().zip(&b.positions) {
            for (pa, pb) in ta.iter().zip(tb) {
                match (pa, pb) {
                    (None, None) => {}
                    (Some(pa), Some(pb)) => {
                        for k in 0..3 {
                            let tol = 1e-7 * pa[k].abs().max(1.0);
                            assert!((pa[k] - pb[k]).abs() <= tol, "{pa} vs {pb}");
                        }
                    }
                    _ => panic!("gap mismatch: {pa:?} vs {pb:?}"),
                }
            }
        }
    }

    #[test]
    fn round_trip_with_gaps() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.c3d");
        let t = sample(&["PALM_1", "PALM_2", "I_PROX_1"], 50);
        write_c3d(&path, &t).unwrap();
        // No temporary file left behind.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        let back = read_c3d(&path, &no_map()).unwrap();
        // Deterministic bytes.
        let again = dir.path().join("again.c3d");
        write_c3d(&again, &t).unwrap();
        assert_eq!(
            std::fs::read(&again).unwrap(),
            std::fs::read(&path).unwrap()
        );
        std::fs::remove_file(&again).unwrap();
        assert_eq!(back.frame_rate, 120.0);
        assert_eq!(back.source, path);
        assert_same_within_f32(&t, &back);

        // c3dio on its own sees the same file: labels, rate, units, values and gaps.
        let c3d = C3d::load_path(path.clone()).unwrap();
        assert_eq!(c3d.points.labels, t.labels);
        assert_eq!(c3d.points.frame_rate, 120.0);
        assert_eq!(c3d.points.units.iter().collect::<String>().trim(), "mm");
        assert_eq!(c3d.points.rows(), 50);
        for (m, track) in t.positions.iter().enumerate() {
            for (f, p) in track.iter().enumerate() {
                let mp = c3d.points.get(f, m).unwrap();
                assert_eq!(mp.residual < 0.0, p.is_none(), "marker {m} frame {f}");
                if let Some(p) = p {
                    assert_eq!(mp.point[0], p.x as f32);
                }
            }
        }

        // The bytes follow the user guide: whole blocks, residual word -1.0 for a gap, 0.0 else,
        // POINT:DATA_START equal to header word 9.
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(bytes.len() % BLOCK, 0);
        let ds = u16::from_le_bytes([bytes[16], bytes[17]]) as usize;
        let params = walk_parameters(&bytes[BLOCK..BLOCK * (ds - 1)], Proc::Intel).unwrap();
        let p = params.get("POINT", "DATA_START").unwrap();
        assert_eq!(p.ints(Proc::Intel).unwrap(), vec![ds as i16]);
        assert_eq!(bytes[BLOCK + 2] as usize, ds - 2);
        let word = |f: usize, m: usize| {
            let at = BLOCK * (ds - 1) + 16 * (f * 3 + m) + 12;
            f32::from_le_bytes(bytes[at..at + 4].try_into().unwrap())
        };
        assert_eq!(word(0, 2), -1.0);
        assert_eq!(word(0, 0), 0.0);
        assert_eq!(word(3, 0), -1.0);
    }

    /// A file written by c3dio directly, with the given units and positions (in those units);
    /// `None` = a gap (negative residual). Float data unless `integer` (scale 0.1).
    fn c3dio_file(
        units: &str,
        labels: &[&str],
        frames: &[Vec<Option<[f32; 3]>>],
        integer: bool,
    ) -> Vec<u8> {
        let mut c3d = C3d::new();
        if integer {
            c3d.points.format = c3dio::DataFormat::Integer;
        }
        for g in REQUIRED_GROUPS {
            c3d.parameters.insert_group(g, String::new());
        }
        let mut u = [' '; 4];
        for (i, c) in units.chars().take(4).enumerate() {
            u[i] = c;
        }
        c3d.points.units = u;
        c3d.points.labels = labels.iter().map(|s| s.to_string()).collect();
        c3d.points.descriptions = vec![String::new(); labels.len()];
        c3d.points.frame_rate = 200.0;
        c3d.points.scale_factor = 0.1;
        c3d.points.first_frame = 1;
        c3d.points.last_frame = frames.len() as u16;
        for row in frames {
            let row = row
                .iter()
                .map(|p| match p {
                    Some(p) => {
                        let mut mp = MarkerPoint::new(p[0], p[1], p[2]);
                        // c3dio's integer writer flags a zero residual as invalid.
                        mp.residual = 0.1;
                        mp
                    }
                    None => {
                        let mut mp = MarkerPoint::new(0.0, 0.0, 0.0);
                        mp.residual = -0.1;
                        mp
                    }
                })
                .collect();
            c3d.points.points.push_row(row);
        }
        c3d.parameters
            .insert("POINT", "RATE", Parameter::float(200.0));
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("raw.c3d");
        c3d.write_path(path.clone()).unwrap();
        std::fs::read(path).unwrap()
    }

    #[test]
    fn units_are_honoured() {
        let frames = vec![
            vec![Some([0.5, -0.25, 1.0]), None],
            vec![Some([0.125, 0.0, 2.0]), Some([1.0, 2.0, 3.0])],
        ];
        let name = Path::new("metres.c3d");
        let t = read_c3d_bytes(
            &c3dio_file("m", &["A", "B"], &frames, false),
            &no_map(),
            name,
        )
        .unwrap();
        assert_eq!(t.frame_rate, 200.0);
        assert_eq!(t.get("A", 0), Some(Point::new(500.0, -250.0, 1000.0)));
        assert_eq!(t.get("A", 1), Some(Point::new(125.0, 0.0, 2000.0)));
        assert_eq!(t.get("B", 0), None);
        assert_eq!(t.get("B", 1), Some(Point::new(1000.0, 2000.0, 3000.0)));
        let t = read_c3d_bytes(
            &c3dio_file("cm", &["A", "B"], &frames, false),
            &no_map(),
            name,
        )
        .unwrap();
        assert_eq!(t.get("A", 0), Some(Point::new(5.0, -2.5, 10.0)));
        let t = read_c3d_bytes(
            &c3dio_file("mm", &["A", "B"], &frames, false),
            &no_map(),
            name,
        )
        .unwrap();
        assert_eq!(t.get("B", 1), Some(Point::new(1.0, 2.0, 3.0)));
        let e = read_c3d_bytes(
            &c3dio_file("ft", &["A", "B"], &frames, false),
            &no_map(),
            name,
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.starts_with("metres.c3d: ") && e.contains("POINT:UNITS is 'ft'"),
            "{e}"
        );
    }

    #[test]
    fn integer_format_is_scaled() {
        let frames = vec![
            vec![Some([12.3, -4.5, 100.0]), None],
            vec![Some([0.0, 0.1, -0.2]), Some([1.0, 2.0, 3.0])],
        ];
        let bytes = c3dio_file("cm", &["A", "B"], &frames, true);
        // Header word 7 positive: integer data.
        assert!(f32::from_le_bytes(bytes[12..16].try_into().unwrap()) > 0.0);
        let t = read_c3d_bytes(&bytes, &no_map(), Path::new("int.c3d")).unwrap();
        assert_eq!(t.get("B", 0), None);
        for (f, row) in frames.iter().enumerate() {
            for (m, p) in row.iter().enumerate() {
                let Some(p) = p else { continue };
                let got = t.get(["A", "B"][m], f).unwrap();
                for k in 0..3 {
                    // Integer data is quantised to the scale factor, 0.1 cm = 1 mm.
                    assert!((got[k] - 10.0 * p[k] as f64).abs() <= 0.5 + 1e-4, "{got}");
                }
            }
        }
    }

    #[test]
    fn labels_mapping_and_vicon_prefix() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.c3d");
        let raw = ["LHand1", "Sub01:PALM_2", "Sub01:Foo", "Sub01:RH3", "I_NAIL"];
        write_c3d(&path, &sample(&raw, 12)).unwrap();
        let map: BTreeMap<String, String> = [("LHand1", "PALM_1"), ("RH3", "PALM_3")]
            .into_iter()
            .map(|(a, b)| (a.to_string(), b.to_string()))
            .collect();
        let t = read_c3d(&path, &map).unwrap();
        assert_eq!(
            t.labels,
            ["PALM_1", "PALM_2", "Sub01:Foo", "PALM_3", "I_NAIL"]
        );
        // Mapping changes names, not data.
        let plain = read_c3d(&path, &no_map()).unwrap();
        assert_eq!(plain.labels[0], "LHand1");
        assert_eq!(t.positions, plain.positions);

        // Two labels that end up with one name: an error naming both.
        write_c3d(&path, &sample(&["PALM_1", "S:PALM_1"], 5)).unwrap();
        let e = read_c3d(&path, &no_map()).unwrap_err().to_string();
        assert!(e.contains("'PALM_1'") && e.contains("'S:PALM_1'"), "{e}");
        assert!(e.starts_with(&path.display().to_string()), "{e}");
        write_c3d(&path, &sample(&["X", "PALM_1"], 5)).unwrap();
        let map = [("X".to_string(), "PALM_1".to_string())].into();
        let e = read_c3d(&path, &map).unwrap_err().to_string();
        assert!(e.contains("'X'") && e.contains("'PALM_1'"), "{e}");
    }

    #[test]
    fn require_on_a_read_trial_names_file_and_marker() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("index.c3d");
        write_c3d(&path, &sample(&["PALM_1", "I_PROX_1"], 5)).unwrap();
        let t = read_c3d(&path, &no_map()).unwrap();
        let e = t
            .require(&["PALM_1", "I_PROX_2", "I_PROX_3"])
            .unwrap_err()
            .to_string();
        assert!(e.starts_with(&path.display().to_string()), "{e}");
        assert!(e.contains("'I_PROX_2'") && !e.contains("I_PROX_3"), "{e}");
    }

    fn valid_file() -> &'static [u8] {
        static BYTES: OnceLock<Vec<u8>> = OnceLock::new();
        BYTES.get_or_init(|| {
            let dir = tempfile::tempdir().unwrap();
            let path = dir.path().join("v.c3d");
            write_c3d(&path, &sample(&["PALM_1", "PALM_2", "I_MID_1"], 40)).unwrap();
            std::fs::read(path).unwrap()
        })
    }

    fn read_err(bytes: &[u8]) -> String {
        let e = read_c3d_bytes(bytes, &no_map(), Path::new("S01/trials/x.c3d"))
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("S01/trials/x.c3d: "), "{e}");
        assert!(!e.contains('\n'), "{e}");
        e
    }

    #[test]
    fn bad_files_name_the_fault() {
        let good = valid_file();
        assert!(read_err(&good[..700]).contains("not a C3D file"));
        let mut b = good.to_vec();
        b[1] = 0x51;
        assert!(read_err(&b).contains("header byte 2"));
        // Truncated data: the frame count no longer fits.
        let ds = u16::from_le_bytes([good[16], good[17]]) as usize;
        let e = read_err(&good[..BLOCK * (ds - 1) + 16 * 3 * 20]);
        assert!(e.contains("truncated"), "{e}");
        // Header frame rate disagreeing with POINT:RATE.
        let mut b = good.to_vec();
        b[20..24].copy_from_slice(&100.0f32.to_le_bytes());
        assert!(read_err(&b).contains("POINT:RATE (120 Hz)"));
        // Zero rate in both places.
        b[20..24].copy_from_slice(&0.0f32.to_le_bytes());
        assert!(read_err(&b).contains("header word 11"));
        // Data start pointing past the end.
        let mut b = good.to_vec();
        b[16..18].copy_from_slice(&500u16.to_le_bytes());
        assert!(read_err(&b).contains("header word 9"));
        // A marker count that disagrees with POINT:USED.
        let mut b = good.to_vec();
        b[2..4].copy_from_slice(&2u16.to_le_bytes());
        assert!(read_err(&b).contains("POINT:USED is 3"));
    }

    /// Frame counts past the header's 16 bits: written as the C3D community asks and read back
    /// exactly, by this reader and by what `c3dio` alone makes of the same file.
    #[test]
    fn frame_counts_beyond_16_bits_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        for frames in [65_535, 65_536, 100_000, 140_000] {
            let path = dir.path().join(format!("long{frames}.c3d"));
            let mut t = sample(&["PALM_1", "PALM_2"], 3);
            // Each frame's x is its index, so a frame lost or shifted anywhere shows.
            t.positions = (0..2)
                .map(|m| {
                    (0..frames)
                        .map(|f| (f % 1000 != 7).then(|| Point::new(f as f64, m as f64, 0.5)))
                        .collect()
                })
                .collect();
            write_c3d(&path, &t).unwrap();
            let back = read_c3d(&path, &no_map()).unwrap();
            assert_eq!(back.n_frames(), frames);
            assert_eq!(back.positions, t.positions);

            let bytes = std::fs::read(&path).unwrap();
            let ds = u16::from_le_bytes([bytes[16], bytes[17]]) as usize;
            let params = walk_parameters(&bytes[BLOCK..BLOCK * (ds - 1)], Proc::Intel).unwrap();
            let words = |name: &str| {
                let v = params
                    .get("TRIAL", name)
                    .unwrap()
                    .ints(Proc::Intel)
                    .unwrap();
                v[0] as u16 as usize + ((v[1] as u16 as usize) << 16)
            };
            let header_last = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
            let point_frames = params.get("POINT", "FRAMES").unwrap();
            if frames <= 65_535 {
                assert_eq!(
                    point_frames.ints(Proc::Intel).unwrap(),
                    vec![frames as u16 as i16]
                );
                assert!(params.get("TRIAL", "ACTUAL_END_FIELD").is_none());
                assert_eq!(header_last, frames);
            } else {
                // The standard's float POINT:FRAMES, the header at its 16-bit ceiling, and the
                // 32-bit frame numbers of the TRIAL group.
                assert_eq!(
                    point_frames.floats(Proc::Intel).unwrap(),
                    vec![frames as f32]
                );
                let long = params.get("POINT", "LONG_FRAMES").unwrap();
                assert_eq!(long.floats(Proc::Intel).unwrap(), vec![frames as f32]);
                assert_eq!(words("ACTUAL_START_FIELD"), 1);
                assert_eq!(words("ACTUAL_END_FIELD"), frames);
                assert_eq!(header_last, 65_535);
            }
            // c3dio alone takes the maximum of its (one short) TRIAL count and LONG_FRAMES.
            let c3d = C3d::load_path(path.clone()).unwrap();
            assert_eq!(c3d.points.rows(), frames);
            std::fs::remove_file(&path).unwrap();
        }
    }

    /// A file as another writer makes it past 65,535 frames: an integer POINT:FRAMES stuck at
    /// 65,535, no LONG_FRAMES, and the count only in TRIAL:ACTUAL_*_FIELD (which `c3dio` alone
    /// reads one frame short).
    #[test]
    fn trial_fields_alone_give_the_frame_count() {
        let frames = 65_536 + 999;
        let mut t = sample(&["PALM_1"], 3);
        t.positions = vec![(0..frames)
            .map(|f| Some(Point::new(f as f64, 0.0, 0.0)))
            .collect()];
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("vicon.c3d");
        write_c3d(&path, &t).unwrap();
        let mut bytes = std::fs::read(&path).unwrap();
        let ds = u16::from_le_bytes([bytes[16], bytes[17]]) as usize;
        let params = walk_parameters(&bytes[BLOCK..BLOCK * (ds - 1)], Proc::Intel).unwrap();
        // LONG_FRAMES renamed out of the way, POINT:FRAMES a float 65,535.
        let long = params.get("POINT", "LONG_FRAMES").unwrap();
        // Before the data: offset word, type, dimension count and one dimension.
        let name_at = BLOCK + long.at - 5 - "LONG_FRAMES".len();
        assert_eq!(&bytes[name_at..name_at + 11], b"LONG_FRAMES");
        bytes[name_at..name_at + 11].copy_from_slice(b"XLONG_FRAME");
        let at = BLOCK + params.get("POINT", "FRAMES").unwrap().at;
        bytes[at..at + 4].copy_from_slice(&65_535f32.to_le_bytes());
        let c3d = C3d::from_bytes(&bytes).unwrap();
        assert_eq!(c3d.points.rows(), frames - 1, "c3dio alone is one short");
        let back = read_c3d_bytes(&bytes, &no_map(), &path).unwrap();
        assert_eq!(back.n_frames(), frames);
        assert_eq!(back.positions, t.positions);
    }

    #[test]
    fn writer_rejects_what_it_cannot_represent() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("w.c3d");
        let mut t = sample(&["PALM_1"], 3);
        t.labels[0] = "Handrücken".into();
        let e = write_c3d(&path, &t).unwrap_err().to_string();
        assert!(e.contains("'Handrücken'"), "{e}");
        // Beyond 2^24 a float POINT:FRAMES is not exact (checked on the count alone: a
        // trajectory that long would take half a gigabyte).
        let e = check_frame_count(MAX_WRITE_FRAMES + 1).unwrap_err();
        assert!(e.contains("16777217 frames"), "{e}");
        assert!(check_frame_count(0).is_err());
        assert!(check_frame_count(MAX_WRITE_FRAMES).is_ok());
        assert_eq!(MAX_WRITE_FRAMES as f32 as usize, MAX_WRITE_FRAMES);
        let mut t = sample(&["A"], 3);
        t.positions[0][1] = Some(Point::new(1e300, 0.0, 0.0));
        let e = write_c3d(&path, &t).unwrap_err().to_string();
        assert!(e.contains("marker 'A' frame 1"), "{e}");
        assert!(!path.exists());
    }

    /// Outcome of one read of mutated bytes: an error or a self-consistent result, and never a
    /// panic inside c3dio (the checks must stop the input before it).
    fn check_mutant(bytes: &[u8]) {
        let before = C3DIO_PANICS.load(Ordering::Relaxed);
        if let Ok(t) = read_c3d_bytes(bytes, &no_map(), Path::new("m.c3d")) {
            assert!(t.n_frames() >= 1 && !t.labels.is_empty());
            assert!(t.positions.iter().all(|p| p.len() == t.n_frames()));
            // Every sample came from 16 (float) or 8 (integer) bytes of the input.
            assert!(8 * t.n_frames() * t.labels.len() <= bytes.len());
        }
        assert_eq!(
            C3DIO_PANICS.load(Ordering::Relaxed),
            before,
            "c3dio panicked"
        );
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        #[test]
        fn truncated_files_never_panic(len in 0usize..3000) {
            let good = valid_file();
            check_mutant(&good[..len.min(good.len())]);
        }

        #[test]
        fn mutated_structure_never_panics(
            edits in proptest::collection::vec((0usize..1536, any::<u8>()), 1..8)
        ) {
            let mut b = valid_file().to_vec();
            for (at, v) in edits {
                b[at] = v;
            }
            check_mutant(&b);
        }

        #[test]
        fn mutated_header_words_never_panic(
            edits in proptest::collection::vec((0usize..12, any::<u16>()), 1..4)
        ) {
            let mut b = valid_file().to_vec();
            for (w, v) in edits {
                b[2 * w..2 * w + 2].copy_from_slice(&v.to_le_bytes());
            }
            check_mutant(&b);
        }

        #[test]
        fn mutated_anywhere_never_panics(
            edits in proptest::collection::vec((any::<Index>(), any::<u8>()), 1..16)
        ) {
            let mut b = valid_file().to_vec();
            let n = b.len();
            for (at, v) in edits {
                b[at.index(n)] = v;
            }
            check_mutant(&b);
        }
    }
}
