//! Encoding trajectories as a C3D file (user guide chapters 2-5): Intel processor type, float
//! point data in mm, one parameter block section holding what readers need to find, scale and
//! name the points, and no analog data.

use super::format::{BLOCK, CHAR, FLOAT, INT, INTEL_BYTE};
use crate::mocap::trajectories::Trajectories;
use std::collections::BTreeSet;

/// Largest frame count `write_c3d` accepts: beyond 65,535 frames `POINT:FRAMES` and
/// `POINT:LONG_FRAMES` are 32-bit floats, exact up to 2^24.
pub const MAX_WRITE_FRAMES: usize = 1 << 24;

/// Frame counts a C3D header (16-bit words 4-5) and an integer `POINT:FRAMES` can hold.
const MAX_SHORT_FRAMES: usize = 65_535;

/// Largest marker count: `POINT:USED` is a signed 16-bit integer.
const MAX_MARKERS: usize = i16::MAX as usize;

/// Labels per `POINT:LABELS`, `LABELS2`, ... parameter: dimensions are single bytes.
const LABELS_PER_PARAM: usize = 255;

/// Largest parameter record after its name: the offset to the next record is a signed 16-bit
/// integer (user guide 4.3).
const MAX_RECORD: usize = i16::MAX as usize;

/// Largest parameter section: its block count is one byte (user guide 4.1).
const MAX_PARAM_BLOCKS: usize = u8::MAX as usize;

/// Group ids of the groups written.
const POINT: u8 = 1;
const ANALOG: u8 = 2;
const FORCE_PLATFORM: u8 = 3;
const TRIAL: u8 = 4;

/// The residual word of a present sample (no residual computed, no camera mask) and of a missing
/// one (negative: invalid, user guide 5.2).
const PRESENT: f32 = 0.0;
const MISSING: f32 = -1.0;

/// The file's bytes: header, parameter section, point data, padded to whole blocks. The output
/// depends only on `traj`, so the same trajectories give the same bytes.
pub(super) fn encode(traj: &Trajectories) -> Result<Vec<u8>, String> {
    check_writable(traj)?;
    let (section, data_start) = parameter_section(traj)?;
    let n = traj.labels.len();
    let frames = traj.n_frames();
    let mut out = Vec::with_capacity(BLOCK * (data_start - 1) + 16 * n * frames + BLOCK);
    out.extend(header(traj, data_start));
    out.extend(section);
    for f in 0..frames {
        for track in &traj.positions {
            let (coords, residual) = match track[f] {
                Some(p) => ([p.x as f32, p.y as f32, p.z as f32], PRESENT),
                None => ([0.0; 3], MISSING),
            };
            for v in coords.into_iter().chain([residual]) {
                out.extend(v.to_le_bytes());
            }
        }
    }
    out.resize(out.len().div_ceil(BLOCK) * BLOCK, 0);
    Ok(out)
}

/// The 512-byte header (user guide 3.1): parameters at block 2, the marker count, no analog
/// words, frames 1..n (at most 65,535, see [`parameter_section`] beyond), scale factor -1 (float
/// data), the data's first block and the frame rate. The rest (event labels, unused words) stays
/// zero.
fn header(traj: &Trajectories, data_start: usize) -> Vec<u8> {
    let mut h = vec![0u8; BLOCK];
    let mut word = |w: usize, v: u16| h[2 * w - 2..2 * w].copy_from_slice(&v.to_le_bytes());
    word(2, traj.labels.len() as u16);
    word(4, 1);
    word(5, traj.n_frames().min(MAX_SHORT_FRAMES) as u16);
    word(9, data_start as u16);
    h[0] = 2;
    h[1] = 0x50;
    h[12..16].copy_from_slice(&(-1.0f32).to_le_bytes());
    h[20..24].copy_from_slice(&(traj.frame_rate as f32).to_le_bytes());
    h
}

/// The parameter section and the block the data starts at. Groups:
/// - POINT: `USED`, `FRAMES`, `DATA_START`, `SCALE` -1 (float data, residual unit 1 mm),
///   `RATE`, `UNITS` "mm", `LABELS` (continued in `LABELS2`, ... beyond 255 markers) and blank
///   `DESCRIPTIONS` split the same way;
/// - ANALOG and FORCE_PLATFORM, each with `USED` 0 (readers look these counts up);
/// - beyond 65,535 frames, as c3d.org's "Maintaining C3D frame count compatibility" asks:
///   `POINT:FRAMES` a float, the header's frame range 1..65,535, and `POINT:LONG_FRAMES` (float)
///   and `TRIAL:ACTUAL_START_FIELD` / `ACTUAL_END_FIELD` (two 16-bit words each, low first) for
///   readers that take the count from those (the Python `c3d` package, Vicon's software).
fn parameter_section(traj: &Trajectories) -> Result<(Vec<u8>, usize), String> {
    let n = traj.labels.len();
    let frames = traj.n_frames();
    let long = frames > MAX_SHORT_FRAMES;
    let mut s = Section::new();
    s.group(POINT, "POINT");
    s.group(ANALOG, "ANALOG");
    s.group(FORCE_PLATFORM, "FORCE_PLATFORM");
    if long {
        s.group(TRIAL, "TRIAL");
    }
    s.ints(POINT, "USED", &[n as i16])?;
    if long {
        s.float(POINT, "FRAMES", frames as f32)?;
        s.float(POINT, "LONG_FRAMES", frames as f32)?;
        let words = |f: usize| [(f & 0xffff) as u16 as i16, (f >> 16) as u16 as i16];
        s.ints(TRIAL, "ACTUAL_START_FIELD", &words(1))?;
        s.ints(TRIAL, "ACTUAL_END_FIELD", &words(frames))?;
    } else {
        s.ints(POINT, "FRAMES", &[frames as u16 as i16])?;
    }
    let data_start_at = s.ints(POINT, "DATA_START", &[0])?;
    s.float(POINT, "SCALE", -1.0)?;
    s.float(POINT, "RATE", traj.frame_rate as f32)?;
    s.text(POINT, "UNITS", "mm")?;
    let width = traj.labels.iter().map(String::len).max().unwrap_or(1);
    let per_param = LABELS_PER_PARAM.min((MAX_RECORD - 7) / width);
    let blank = vec![""; n];
    for (k, (labels, blanks)) in traj
        .labels
        .chunks(per_param)
        .zip(blank.chunks(per_param))
        .enumerate()
    {
        let suffix = if k == 0 {
            String::new()
        } else {
            (k + 1).to_string()
        };
        let labels: Vec<&str> = labels.iter().map(String::as_str).collect();
        s.text_list(POINT, &format!("LABELS{suffix}"), &labels)?;
        s.text_list(POINT, &format!("DESCRIPTIONS{suffix}"), blanks)?;
    }
    s.ints(ANALOG, "USED", &[0])?;
    s.ints(FORCE_PLATFORM, "USED", &[0])?;
    let mut section = s.finish();
    let blocks = section.len() / BLOCK;
    if blocks > MAX_PARAM_BLOCKS {
        return Err(format!(
            "cannot write {n} markers: their labels need {blocks} parameter blocks, more than \
             the {MAX_PARAM_BLOCKS} a C3D file can have"
        ));
    }
    let data_start = 2 + blocks;
    section[2] = blocks as u8;
    section[data_start_at..data_start_at + 2].copy_from_slice(&(data_start as i16).to_le_bytes());
    Ok((section, data_start))
}

/// A parameter section being written (user guide 4.2, 4.3), Intel byte order, no descriptions.
struct Section {
    bytes: Vec<u8>,
}

impl Section {
    /// The four-byte section header: byte 3 (the block count) is set by the caller.
    fn new() -> Section {
        Section {
            bytes: vec![1, 0x50, 0, INTEL_BYTE],
        }
    }

    fn group(&mut self, id: u8, name: &str) {
        self.bytes.extend([name.len() as u8, (-(id as i8)) as u8]);
        self.bytes.extend(name.as_bytes());
        // Offset word, description length: the next record follows.
        self.bytes.extend(3u16.to_le_bytes());
        self.bytes.push(0);
    }

    /// Append a parameter record and return the file-section offset of its data.
    fn param(
        &mut self,
        group: u8,
        name: &str,
        kind: i8,
        dims: &[usize],
        data: &[u8],
    ) -> Result<usize, String> {
        let record = 2 + 1 + 1 + dims.len() + data.len() + 1;
        if record > MAX_RECORD || dims.iter().any(|&d| d > u8::MAX as usize) {
            return Err(format!("parameter {name} is too large to write"));
        }
        self.bytes.extend([name.len() as u8, group]);
        self.bytes.extend(name.as_bytes());
        self.bytes.extend((record as u16).to_le_bytes());
        self.bytes.extend([kind as u8, dims.len() as u8]);
        self.bytes.extend(dims.iter().map(|&d| d as u8));
        let at = self.bytes.len();
        self.bytes.extend(data);
        self.bytes.push(0);
        Ok(at)
    }

    /// 16-bit integers, as a list even when there is one (dimension 1 rather than none, which
    /// some readers do not expect).
    fn ints(&mut self, group: u8, name: &str, values: &[i16]) -> Result<usize, String> {
        let data: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        self.param(group, name, INT, &[values.len()], &data)
    }

    /// One float, as a one-element list like [`Section::ints`].
    fn float(&mut self, group: u8, name: &str, value: f32) -> Result<usize, String> {
        self.param(group, name, FLOAT, &[1], &value.to_le_bytes())
    }

    /// One string: one dimension, its length.
    fn text(&mut self, group: u8, name: &str, value: &str) -> Result<usize, String> {
        self.param(group, name, CHAR, &[value.len()], value.as_bytes())
    }

    /// Strings padded with blanks to the longest (at least one character): two dimensions,
    /// width and count, however many there are.
    fn text_list(&mut self, group: u8, name: &str, values: &[&str]) -> Result<usize, String> {
        let width = values.iter().map(|v| v.len()).max().unwrap_or(0).max(1);
        let mut data = Vec::with_capacity(width * values.len());
        for v in values {
            data.extend(v.bytes());
            data.resize(data.len() + width - v.len(), b' ');
        }
        self.param(group, name, CHAR, &[width, values.len()], &data)
    }

    /// The section ended by a zero record and padded to whole blocks.
    fn finish(mut self) -> Vec<u8> {
        self.bytes.extend([0, 0]);
        self.bytes
            .resize(self.bytes.len().div_ceil(BLOCK) * BLOCK, 0);
        self.bytes
    }
}

/// What the file can represent faithfully; a message naming the marker otherwise.
pub(super) fn check_writable(traj: &Trajectories) -> Result<(), String> {
    let n = traj.labels.len();
    let frames = traj.n_frames();
    if n == 0 || n > MAX_MARKERS {
        return Err(format!(
            "cannot write {n} markers (1 to {MAX_MARKERS} fit in POINT:USED)"
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
    let mut seen = BTreeSet::new();
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
        if !seen.insert(label.as_str()) {
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

/// A frame count [`encode`] can write exactly (1 to [`MAX_WRITE_FRAMES`]).
pub(super) fn check_frame_count(frames: usize) -> Result<(), String> {
    if frames == 0 || frames > MAX_WRITE_FRAMES {
        return Err(format!(
            "cannot write {frames} frames (1 to {MAX_WRITE_FRAMES} are exact in POINT:FRAMES)"
        ));
    }
    Ok(())
}
