//! Decoding a C3D file's header (user guide chapter 3), the parameters the point data depends on
//! (chapter 4) and the 3D point samples (chapter 5).
//!
//! Every count that sizes an allocation or a loop (markers, analog words, frames) is checked
//! against the bytes present before it is used, so a corrupt or hostile file costs at most a few
//! times its own size and every sample read lies inside it.

use super::format::{walk_parameters, Param, Params, Proc, BLOCK, CHAR};
use crate::geometry::Point;
use crate::io::Units;

/// What the header and parameter checks established: where each sample is and how to decode it.
#[derive(Debug)]
pub(super) struct Layout {
    proc: Proc,
    pub(super) n_frames: usize,
    pub(super) units: Units,
    pub(super) rate: f32,
    /// One per point, trimmed, in column order.
    pub(super) labels: Vec<String>,
    /// File offset of the first frame (header word 9).
    data_at: usize,
    /// Bytes per frame: four words per point, then the frame's analog words.
    frame_bytes: usize,
    encoding: Encoding,
}

/// How the point samples are stored (user guide 5.2, header word 7 / `POINT:SCALE`).
#[derive(Clone, Copy, Debug, PartialEq)]
enum Encoding {
    /// 32-bit floats in the file's units (scale factor zero or negative).
    Float,
    /// 16-bit integers, times the scale factor for the file's units.
    Integer { scale: f64 },
}

impl Encoding {
    fn word_bytes(self) -> usize {
        match self {
            Encoding::Float => 4,
            Encoding::Integer { .. } => 2,
        }
    }
}

impl Layout {
    /// Marker `m` in frame `f`, in mm: `None` when the sample is missing (its residual word is
    /// negative, user guide 5.2) or its coordinates are not finite. `m` and `f` must be within
    /// the layout's counts, which [`check_layout`] checked against the file's length.
    pub(super) fn sample_mm(&self, bytes: &[u8], f: usize, m: usize) -> Option<Point> {
        let wb = self.encoding.word_bytes();
        let at = self.data_at + f * self.frame_bytes + m * 4 * wb;
        let words = bytes.get(at..at + 4 * wb)?;
        let to_mm = self.units.to_mm();
        let [x, y, z, residual] = match self.encoding {
            Encoding::Float => {
                let w = |k: usize| {
                    let b = &words[4 * k..4 * k + 4];
                    f64::from(self.proc.f32([b[0], b[1], b[2], b[3]]))
                };
                [w(0), w(1), w(2), w(3)]
            }
            Encoding::Integer { scale } => {
                let w = |k: usize| f64::from(self.proc.i16([words[2 * k], words[2 * k + 1]]));
                [w(0) * scale, w(1) * scale, w(2) * scale, w(3)]
            }
        };
        // NaN is no residual at all; -0.0 is a zero residual.
        if residual.is_nan() || residual < 0.0 {
            return None;
        }
        let p = Point::new(x * to_mm, y * to_mm, z * to_mm);
        p.iter().all(|c| c.is_finite()).then_some(p)
    }
}

/// The header words a reader needs (user guide 3.1), decoded in the file's number format.
struct Header {
    n_points: usize,
    /// Analog words stored after the points of each frame (all channels' samples).
    analog_words: usize,
    first: u16,
    last: u16,
    scale: f32,
    data_start: usize,
    analog_per_channel: usize,
    rate: f32,
}

impl Header {
    fn read(bytes: &[u8], proc: Proc) -> Header {
        // Header word w (1-based) starts at byte 2(w - 1); the caller checked 1,024 bytes exist.
        let word = |w: usize| proc.u16([bytes[2 * w - 2], bytes[2 * w - 1]]);
        let float = |w: usize| {
            let o = 2 * w - 2;
            proc.f32([bytes[o], bytes[o + 1], bytes[o + 2], bytes[o + 3]])
        };
        Header {
            n_points: word(2) as usize,
            analog_words: word(3) as usize,
            first: word(4),
            last: word(5),
            scale: float(7),
            data_start: word(9) as usize,
            analog_per_channel: word(10) as usize,
            rate: float(11),
        }
    }
}

/// Check the header and the parameters the point data depends on, and work out where every
/// sample is; every message names the header word or parameter at fault.
pub(super) fn check_layout(bytes: &[u8]) -> Result<Layout, String> {
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
    let h = Header::read(bytes, proc);
    let (n_points, rate) = (h.n_points, h.rate);
    if h.data_start < 3 || BLOCK * (h.data_start - 1) > len {
        return Err(format!(
            "data start block {} (header word 9) is not between 3 and the end of the file ({} \
             blocks)",
            h.data_start,
            len.div_ceil(BLOCK)
        ));
    }
    let data_at = BLOCK * (h.data_start - 1);
    let data_len = len - data_at;
    if n_points == 0 {
        return Err("the trial has no markers (header word 2 is 0)".into());
    }
    if h.first > h.last {
        return Err(format!(
            "header frame range {}..{} (words 4 and 5) is reversed",
            h.first, h.last
        ));
    }
    if !h.scale.is_finite() {
        return Err(format!("POINT scale factor (header word 7) is {}", h.scale));
    }
    let encoding = if h.scale > 0.0 {
        Encoding::Integer {
            scale: f64::from(h.scale),
        }
    } else {
        Encoding::Float
    };
    if !(rate.is_finite() && rate > 0.0) {
        return Err(format!(
            "frame rate (header word 11) is {rate}, not a positive number"
        ));
    }
    let frame_bytes = (4 * n_points + h.analog_words) * encoding.word_bytes();
    let header_frames = (h.last - h.first) as u128 + 1;
    if header_frames * frame_bytes as u128 > data_len as u128 {
        return Err(format!(
            "file truncated: header frames {}..{} of {n_points} markers need {} bytes of data, \
             {data_len} follow the data start",
            h.first,
            h.last,
            header_frames * frame_bytes as u128
        ));
    }

    let params = walk_parameters(&bytes[BLOCK..data_at], proc)?;
    check_point_parameters(&params, proc, &h)?;
    check_analog(&params, proc, &h)?;
    let labels = point_labels(&params, n_points)?;
    let units = point_units(&params)?;
    let n_frames = frame_count(&params, proc)?;
    if n_frames == 0 {
        return Err("the trial has no frames (POINT:FRAMES is 0 or missing)".into());
    }
    if n_frames as u128 * frame_bytes as u128 > data_len as u128 {
        return Err(format!(
            "file truncated: {n_frames} frames (POINT:FRAMES) of {n_points} markers need {} bytes \
             of data, {data_len} follow the data start",
            n_frames as u128 * frame_bytes as u128
        ));
    }
    Ok(Layout {
        proc,
        n_frames,
        units,
        rate,
        labels,
        data_at,
        frame_bytes,
        encoding,
    })
}

/// `POINT:USED`, `RATE`, `SCALE` and `DATA_START` against the header, which is what the data is
/// read by: a disagreement means one of them is corrupt, and which one cannot be told.
fn check_point_parameters(params: &Params, proc: Proc, h: &Header) -> Result<(), String> {
    let p = |n: &str| params.get("POINT", n);
    let used = p("USED")
        .and_then(|u| u.count(proc))
        .ok_or("POINT:USED is missing or not a number")?;
    if used != h.n_points {
        return Err(format!(
            "POINT:USED is {used} but the header (word 2) says {} markers",
            h.n_points
        ));
    }
    if let Some(r) = p("RATE") {
        match r.floats(proc).as_deref() {
            Some([v]) if *v == h.rate => {}
            Some([v]) => {
                return Err(format!(
                    "POINT:RATE ({v} Hz) disagrees with the header frame rate ({} Hz)",
                    h.rate
                ))
            }
            _ => return Err("POINT:RATE is not a single float".into()),
        }
    }
    if let Some(s) = p("SCALE") {
        match s.floats(proc).as_deref() {
            Some([v]) if v.abs() == h.scale.abs() => {}
            _ => {
                return Err(format!(
                    "POINT:SCALE disagrees with the header scale factor ({})",
                    h.scale
                ))
            }
        }
    }
    if let Some(d) = p("DATA_START") {
        match d.ints(proc).as_deref() {
            Some([v]) if *v as u16 as usize == h.data_start => {}
            Some([v]) => {
                return Err(format!(
                    "POINT:DATA_START ({}) disagrees with the header's data start block (word 9, \
                     {})",
                    *v as u16, h.data_start
                ))
            }
            _ => return Err("POINT:DATA_START is not a single integer".into()),
        }
    }
    Ok(())
}

/// The analog samples interleaved with the points (user guide 5.3): the header's word 3 counts
/// them per frame and is what the reader skips; `ANALOG:USED` channels times word 10 samples per
/// channel, and `ANALOG:RATE` / `POINT:RATE` samples per channel, must agree with it.
fn check_analog(params: &Params, proc: Proc, h: &Header) -> Result<(), String> {
    let Some(a) = params.get("ANALOG", "USED") else {
        return Ok(());
    };
    let used = match a.ints(proc).as_deref() {
        Some([v]) => *v as u16 as usize,
        _ => return Err("ANALOG:USED is not a single integer".into()),
    };
    if used == 0 {
        return Ok(());
    }
    if used as u64 * h.analog_per_channel as u64 != h.analog_words as u64 {
        return Err(format!(
            "ANALOG:USED ({used}) times the analog samples per frame (header word 10, {}) is not \
             the header's analog count (word 3, {})",
            h.analog_per_channel, h.analog_words
        ));
    }
    if let Some(&[analog_rate]) = params
        .get("ANALOG", "RATE")
        .and_then(|r| r.floats(proc))
        .as_deref()
    {
        let per_frame = f64::from(analog_rate) / f64::from(h.rate);
        if analog_rate > 0.0 && (per_frame - h.analog_per_channel as f64).abs() > 1e-3 * per_frame {
            return Err(format!(
                "ANALOG:RATE ({analog_rate} Hz) over the frame rate ({} Hz) is not the header's \
                 analog samples per frame (word 10, {})",
                h.rate, h.analog_per_channel
            ));
        }
    }
    Ok(())
}

/// `n_points` trimmed labels from `POINT:LABELS`, continued in `LABELS2`, `LABELS3`, ... (the
/// convention beyond 255 markers).
fn point_labels(params: &Params, n_points: usize) -> Result<Vec<String>, String> {
    let mut labels = params
        .get("POINT", "LABELS")
        .and_then(Param::strings)
        .ok_or("POINT:LABELS is missing or not text")?;
    // Each continuation holds at least one label, so there are at most n_points of them.
    for k in 2..n_points + 2 {
        if labels.len() >= n_points {
            break;
        }
        match params
            .get("POINT", &format!("LABELS{k}"))
            .and_then(Param::strings)
        {
            Some(more) if !more.is_empty() => labels.extend(more),
            _ => break,
        }
    }
    if labels.len() < n_points {
        return Err(format!(
            "POINT:LABELS names {} markers but the file has {n_points}",
            labels.len()
        ));
    }
    labels.truncate(n_points);
    Ok(labels)
}

/// `POINT:UNITS`: the unit of the coordinates (after the scale factor for integer data).
fn point_units(params: &Params) -> Result<Units, String> {
    let text = params
        .get("POINT", "UNITS")
        .filter(|u| u.kind == CHAR)
        .and_then(Param::strings)
        .map(|s| s.concat())
        .ok_or("POINT:UNITS is missing (expected mm, cm or m)")?;
    text.parse()
        .map_err(|_| format!("POINT:UNITS is '{text}' (expected mm, cm or m)"))
}

/// The frame count (user guide 3.1 and 4.4; c3d.org, "The C3D frame count"): `POINT:FRAMES` (an
/// integer up to 65,535, a float beyond), replaced by `TRIAL:ACTUAL_END_FIELD` -
/// `ACTUAL_START_FIELD` + 1 when both are present (each a 32-bit frame number stored as two
/// 16-bit words, low word first), and `POINT:LONG_FRAMES` when that is larger. The header's 16-bit
/// frame range (words 4-5) cannot hold more than 65,535 frames and is not used.
fn frame_count(params: &Params, proc: Proc) -> Result<usize, String> {
    let mut n_frames = params
        .get("POINT", "FRAMES")
        .and_then(|f| f.count(proc))
        .unwrap_or(0);
    let field = |name: &str| -> Result<Option<usize>, String> {
        let Some(f) = params.get("TRIAL", name) else {
            return Ok(None);
        };
        match f.ints(proc) {
            Some(v) if f.dims.len() == 1 && v.len() == 2 => {
                Ok(Some(v[0] as u16 as usize + ((v[1] as u16 as usize) << 16)))
            }
            Some(_) if f.dims.len() <= 1 => Ok(None),
            _ => Err(format!("TRIAL:{name} is not a list of integers")),
        }
    };
    let end = field("ACTUAL_END_FIELD")?;
    let start = field("ACTUAL_START_FIELD")?;
    if let (Some(s), Some(e)) = (start, end) {
        if e < s {
            return Err(format!(
                "TRIAL:ACTUAL_END_FIELD ({e}) is before TRIAL:ACTUAL_START_FIELD ({s})"
            ));
        }
        n_frames = e - s + 1;
    }
    if let Some(long) = params
        .get("POINT", "LONG_FRAMES")
        .and_then(|l| l.count(proc))
    {
        n_frames = n_frames.max(long);
    }
    Ok(n_frames)
}
