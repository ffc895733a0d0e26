use super::format::{walk_parameters, Params, Proc, BLOCK};
use super::write::check_frame_count;
use super::*;
use crate::geometry::Point;
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

/// The parameters of an Intel file, found through header word 9 as any reader would.
fn params_of(bytes: &[u8]) -> Params {
    let ds = u16::from_le_bytes([bytes[16], bytes[17]]) as usize;
    walk_parameters(&bytes[BLOCK..BLOCK * (ds - 1)], Proc::Intel).unwrap()
}

fn le_f32(bytes: &[u8], at: usize) -> f32 {
    f32::from_le_bytes(bytes[at..at + 4].try_into().unwrap())
}

fn le_u16(bytes: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([bytes[at], bytes[at + 1]])
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
}

/// The writer's bytes, word by word, against the user guide: header words 1-12, the parameter
/// section's header, the POINT parameters, whole blocks, and the data: x, y, z as floats in mm
/// and a residual word of -1.0 for a gap, 0.0 else.
#[test]
fn written_bytes_follow_the_user_guide() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t.c3d");
    let t = sample(&["PALM_1", "PALM_2", "I_PROX_1"], 50);
    write_c3d(&path, &t).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    assert_eq!(bytes.len() % BLOCK, 0);
    assert_eq!(&bytes[..2], &[2, 0x50]);
    let word = |w: usize| le_u16(&bytes, 2 * w - 2);
    assert_eq!(
        [word(2), word(3), word(4), word(5), word(6)],
        [3, 0, 1, 50, 0]
    );
    assert_eq!(le_f32(&bytes, 12), -1.0);
    assert_eq!(word(10), 0);
    assert_eq!(le_f32(&bytes, 20), 120.0);
    let ds = word(9) as usize;
    assert_eq!(&bytes[BLOCK + 1..BLOCK + 4], &[0x50, (ds - 2) as u8, 84]);

    let params = params_of(&bytes);
    let point = |n: &str| params.get("POINT", n).unwrap();
    assert_eq!(point("DATA_START").ints(Proc::Intel).unwrap(), [ds as i16]);
    assert_eq!(point("USED").ints(Proc::Intel).unwrap(), [3]);
    assert_eq!(point("FRAMES").ints(Proc::Intel).unwrap(), [50]);
    assert_eq!(point("SCALE").floats(Proc::Intel).unwrap(), [-1.0]);
    assert_eq!(point("RATE").floats(Proc::Intel).unwrap(), [120.0]);
    assert_eq!(point("UNITS").strings().unwrap(), ["mm"]);
    assert_eq!(point("LABELS").dims, [8, 3]);
    assert_eq!(point("LABELS").strings().unwrap(), t.labels);
    assert_eq!(point("DESCRIPTIONS").strings().unwrap(), ["", "", ""]);
    assert_eq!(
        params.get("ANALOG", "USED").unwrap().ints(Proc::Intel),
        Some(vec![0])
    );
    assert!(params.get("POINT", "LONG_FRAMES").is_none());

    for (m, track) in t.positions.iter().enumerate() {
        for (f, p) in track.iter().enumerate() {
            let at = BLOCK * (ds - 1) + 16 * (f * 3 + m);
            let w: Vec<f32> = (0..4).map(|k| le_f32(&bytes, at + 4 * k)).collect();
            match p {
                Some(p) => assert_eq!(w, [p.x as f32, p.y as f32, p.z as f32, 0.0]),
                None => assert_eq!(w, [0.0, 0.0, 0.0, -1.0]),
            }
        }
    }
    assert!(t.positions[2][0].is_none() && t.positions[0][3].is_none());
}

// ---------------------------------------------------------------------------------------------
// Files of other writers, built by hand from the user guide

/// How a hand-built file states its frame count in `POINT:FRAMES`.
#[derive(Clone, Copy)]
enum Frames {
    /// A 16-bit integer, clamped to 65,535 as writers do past it.
    Int,
    /// A float.
    Float,
}

/// A C3D file built by hand from the user guide, sharing no code with the writer: any processor
/// type, integer or float data, analog channels interleaved, scalar (dimensionless) parameters,
/// and the last record's offset 0 ending the parameter section.
struct GuideFile {
    proc: Proc,
    /// Header word 7 and `POINT:SCALE`: positive for integer data (the size of one count in
    /// `units`), negative for float data.
    scale: f32,
    units: &'static str,
    rate: f32,
    labels: Vec<String>,
    /// `points[f][m]` in `units`; `None` is written with a residual word of -1.
    points: Vec<Vec<Option<[f32; 3]>>>,
    /// Analog channels and samples per channel per frame.
    analog: (usize, usize),
    frames: Frames,
    /// `TRIAL:ACTUAL_START_FIELD` and `ACTUAL_END_FIELD`.
    trial: Option<(u32, u32)>,
    long_frames: Option<f32>,
}

impl GuideFile {
    fn new(labels: &[&str], points: Vec<Vec<Option<[f32; 3]>>>) -> GuideFile {
        GuideFile {
            proc: Proc::Intel,
            scale: -1.0,
            units: "mm",
            rate: 200.0,
            labels: labels.iter().map(|s| s.to_string()).collect(),
            points,
            analog: (0, 0),
            frames: Frames::Int,
            trial: None,
            long_frames: None,
        }
    }

    fn int(&self, v: i16) -> [u8; 2] {
        match self.proc {
            Proc::Mips => v.to_be_bytes(),
            _ => v.to_le_bytes(),
        }
    }

    /// IEEE in the processor's byte order, or VAX F: the IEEE bits of 4v (VAX's exponent is
    /// biased by two more) with the two 16-bit words swapped.
    fn float(&self, v: f32) -> [u8; 4] {
        match self.proc {
            Proc::Intel => v.to_le_bytes(),
            Proc::Mips => v.to_be_bytes(),
            // VAX has no negative zero: that bit pattern is the reserved operand.
            Proc::Dec if v == 0.0 => [0; 4],
            Proc::Dec => {
                let b = (4.0 * v).to_le_bytes();
                [b[2], b[3], b[0], b[1]]
            }
        }
    }

    fn integer_data(&self) -> bool {
        self.scale > 0.0
    }

    fn parameter_section(&self, data_start: u16) -> Vec<u8> {
        let proc_byte = match self.proc {
            Proc::Intel => 84,
            Proc::Dec => 85,
            Proc::Mips => 86,
        };
        let mut records: Vec<Vec<u8>> = Vec::new();
        // name length, id, name, offset to the next record, then `rest`.
        let mut record = |id: i8, name: &str, rest: Vec<u8>| {
            let mut r = vec![name.len() as u8, id as u8];
            r.extend(name.as_bytes());
            r.extend(self.int(2 + rest.len() as i16));
            r.extend(rest);
            records.push(r);
        };
        let param = |kind: i8, dims: &[usize], data: Vec<u8>| {
            let mut r = vec![kind as u8, dims.len() as u8];
            r.extend(dims.iter().map(|&d| d as u8));
            r.extend(data);
            r.push(0);
            r
        };
        let int = |v: i16| param(2, &[], self.int(v).to_vec());
        let float = |v: f32| param(4, &[], self.float(v).to_vec());
        let n = self.labels.len();
        let (channels, per_channel) = self.analog;
        record(-1, "POINT", vec![0]);
        record(-2, "ANALOG", vec![0]);
        record(1, "USED", int(n as i16));
        record(1, "SCALE", float(self.scale));
        record(1, "RATE", float(self.rate));
        record(1, "DATA_START", int(data_start as i16));
        record(
            1,
            "UNITS",
            param(-1, &[self.units.len()], self.units.into()),
        );
        let frames = self.points.len();
        record(
            1,
            "FRAMES",
            match self.frames {
                Frames::Int => int(frames.min(65_535) as u16 as i16),
                Frames::Float => float(frames as f32),
            },
        );
        if let Some(long) = self.long_frames {
            record(1, "LONG_FRAMES", float(long));
        }
        let width = self.labels.iter().map(String::len).max().unwrap_or(1);
        for (k, chunk) in self.labels.chunks(255).enumerate() {
            let name = if k == 0 {
                "LABELS".to_string()
            } else {
                format!("LABELS{}", k + 1)
            };
            let text: Vec<u8> = chunk
                .iter()
                .flat_map(|l| format!("{l:width$}").into_bytes())
                .collect();
            record(1, &name, param(-1, &[width, chunk.len()], text));
        }
        record(2, "USED", int(channels as i16));
        record(2, "RATE", float(self.rate * per_channel as f32));
        if let Some((start, end)) = self.trial {
            record(-3, "TRIAL", vec![0]);
            for (name, frame) in [("ACTUAL_START_FIELD", start), ("ACTUAL_END_FIELD", end)] {
                let words = [frame as u16 as i16, (frame >> 16) as u16 as i16];
                let data = words.iter().flat_map(|&w| self.int(w)).collect();
                record(3, name, param(2, &[2], data));
            }
        }
        let mut s = vec![1, 0x50, 0, proc_byte];
        let last = records.len() - 1;
        for (i, mut r) in records.into_iter().enumerate() {
            if i == last {
                // Offset 0: the last record.
                let at = 2 + r[0] as usize;
                r[at..at + 2].fill(0);
            }
            s.extend(r);
        }
        s.resize(s.len().div_ceil(BLOCK) * BLOCK, 0);
        s[2] = (s.len() / BLOCK) as u8;
        s
    }

    fn bytes(&self) -> Vec<u8> {
        let blocks = self.parameter_section(0).len() / BLOCK;
        let data_start = 2 + blocks as u16;
        let (channels, per_channel) = self.analog;
        let frames = self.points.len();
        let mut out = vec![0u8; BLOCK];
        out[0] = 2;
        out[1] = 0x50;
        let mut word = |w: usize, b: &[u8]| out[2 * w - 2..2 * w - 2 + b.len()].copy_from_slice(b);
        word(2, &self.int(self.labels.len() as i16));
        word(3, &self.int((channels * per_channel) as i16));
        word(4, &self.int(1));
        word(5, &self.int(frames.min(65_535) as u16 as i16));
        word(7, &self.float(self.scale));
        word(9, &self.int(data_start as i16));
        word(10, &self.int(per_channel as i16));
        word(11, &self.float(self.rate));
        out.extend(self.parameter_section(data_start));
        for row in &self.points {
            for p in row {
                if self.integer_data() {
                    let (xyz, residual) = match p {
                        Some(p) => (p.map(|c| (c / self.scale).round() as i16), 0x0503),
                        None => ([0; 3], -1),
                    };
                    for v in xyz.into_iter().chain([residual]) {
                        out.extend(self.int(v));
                    }
                } else {
                    // Camera mask 5, residual 3 as the float 0x0503.
                    let (xyz, residual) = p.map_or(([0.0; 3], -1.0), |p| (p, 1283.0));
                    for v in xyz.into_iter().chain([residual]) {
                        out.extend(self.float(v));
                    }
                }
            }
            // Analog samples, sample by sample, channel by channel: negative values, so that a
            // misaligned read would show as gaps and wrong coordinates.
            for s in 0..per_channel {
                for c in 0..channels {
                    let v = -1000 - (10 * c + s) as i16;
                    if self.integer_data() {
                        out.extend(self.int(v));
                    } else {
                        out.extend(self.float(f32::from(v)));
                    }
                }
            }
        }
        out.resize(out.len().div_ceil(BLOCK) * BLOCK, 0);
        out
    }
}

/// `frames` frames of `n` markers with exactly representable coordinates (multiples of 1/8 and
/// of the integer scale 0.5 used below), every fifth sample of marker 1 a gap.
fn guide_points(n: usize, frames: usize) -> Vec<Vec<Option<[f32; 3]>>> {
    (0..frames)
        .map(|f| {
            (0..n)
                .map(|m| {
                    (m != 1 || f % 5 != 2)
                        .then(|| [f as f32 * 0.5, -(m as f32) * 2.5, 100.0 + (f % 7) as f32])
                })
                .collect()
        })
        .collect()
}

/// What a guide file's points read as: `points` in mm, with `to_mm` the unit's factor.
fn assert_reads_as(t: &Trajectories, points: &[Vec<Option<[f32; 3]>>], to_mm: f64) {
    assert_eq!(t.n_frames(), points.len());
    for (f, row) in points.iter().enumerate() {
        for (m, p) in row.iter().enumerate() {
            let want = p.map(|p| Point::new(p[0] as f64, p[1] as f64, p[2] as f64) * to_mm);
            assert_eq!(t.positions[m][f], want, "marker {m} frame {f}");
        }
    }
}

#[test]
fn units_are_honoured() {
    let frames = vec![
        vec![Some([0.5, -0.25, 1.0]), None],
        vec![Some([0.125, 0.0, 2.0]), Some([1.0, 2.0, 3.0])],
    ];
    let name = Path::new("metres.c3d");
    let file = |units| GuideFile {
        units,
        ..GuideFile::new(&["A", "B"], frames.clone())
    };
    let t = read_c3d_bytes(&file("m").bytes(), &no_map(), name).unwrap();
    assert_eq!(t.frame_rate, 200.0);
    assert_eq!(t.get("A", 0), Some(Point::new(500.0, -250.0, 1000.0)));
    assert_eq!(t.get("A", 1), Some(Point::new(125.0, 0.0, 2000.0)));
    assert_eq!(t.get("B", 0), None);
    assert_eq!(t.get("B", 1), Some(Point::new(1000.0, 2000.0, 3000.0)));
    let t = read_c3d_bytes(&file("cm").bytes(), &no_map(), name).unwrap();
    assert_eq!(t.get("A", 0), Some(Point::new(5.0, -2.5, 10.0)));
    let t = read_c3d_bytes(&file("in").bytes(), &no_map(), name).unwrap();
    assert_eq!(t.get("B", 1), Some(Point::new(1.0, 2.0, 3.0) * 25.4));
    let t = read_c3d_bytes(&file("mm").bytes(), &no_map(), name).unwrap();
    assert_eq!(t.get("B", 1), Some(Point::new(1.0, 2.0, 3.0)));
    let bytes = file("ft").bytes();
    let e = read_c3d_bytes(&bytes, &no_map(), name)
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("metres.c3d: ") && e.contains("POINT:UNITS is 'ft'"),
        "{e}"
    );
    assert_eq!(point_units(&bytes), None);
    assert_eq!(point_units(&file("cm").bytes()), Some(Units::Centimetres));
}

/// Integer data (user guide 5.2): each coordinate a 16-bit count of `POINT:SCALE` units, the
/// residual word's sign the validity.
#[test]
fn integer_format_is_scaled() {
    let frames = vec![
        vec![Some([12.3, -4.5, 100.0]), None],
        vec![Some([0.0, 0.1, -0.2]), Some([1.0, 2.0, 3.0])],
    ];
    let file = GuideFile {
        scale: 0.1,
        units: "cm",
        ..GuideFile::new(&["A", "B"], frames.clone())
    };
    let bytes = file.bytes();
    // Header word 7 positive: integer data, 8 bytes a sample.
    assert!(le_f32(&bytes, 12) > 0.0);
    let t = read_c3d_bytes(&bytes, &no_map(), Path::new("int.c3d")).unwrap();
    assert_eq!(t.get("B", 0), None);
    for (f, row) in frames.iter().enumerate() {
        for (m, p) in row.iter().enumerate() {
            let Some(p) = p else { continue };
            let got = t.get(["A", "B"][m], f).unwrap();
            for k in 0..3 {
                // The count times the scale, in cm, times 10 mm/cm.
                let want = (p[k] / 0.1).round() as f64 * f64::from(0.1f32) * 10.0;
                assert!((got[k] - want).abs() < 1e-9, "{got} vs {want}");
            }
        }
    }
    assert_eq!(t.get("A", 0).unwrap().x.round(), 123.0);
}

/// Analog samples between the frames' points (header word 3 of them, ANALOG:USED channels times
/// ANALOG:RATE / POINT:RATE samples) are stepped over, in integer and float files.
#[test]
fn analog_samples_between_frames_are_skipped() {
    let points = guide_points(3, 30);
    for scale in [-1.0, 0.5] {
        for analog in [(1, 1), (3, 4), (16, 10)] {
            let file = GuideFile {
                scale,
                analog,
                ..GuideFile::new(&["A", "B", "C"], points.clone())
            };
            let t = read_c3d_bytes(&file.bytes(), &no_map(), Path::new("a.c3d")).unwrap();
            assert_reads_as(&t, &points, 1.0);
        }
    }
}

/// DEC (little-endian words, VAX floats) and MIPS (big-endian) files read as the Intel one, in
/// float and integer data, with analog samples.
#[test]
fn processor_types_read_alike() {
    let points = guide_points(4, 25);
    for proc in [Proc::Intel, Proc::Dec, Proc::Mips] {
        for scale in [-1.0, 0.5] {
            let file = GuideFile {
                proc,
                scale,
                analog: (2, 3),
                units: "cm",
                ..GuideFile::new(&["A", "B", "C", "D"], points.clone())
            };
            let bytes = file.bytes();
            let t = read_c3d_bytes(&bytes, &no_map(), Path::new("p.c3d"))
                .unwrap_or_else(|e| panic!("{proc:?} scale {scale}: {e}"));
            assert_eq!(t.frame_rate, 200.0);
            assert_reads_as(&t, &points, 10.0);
            assert_eq!(point_units(&bytes), Some(Units::Centimetres));
        }
    }
}

/// A sample with non-finite coordinates is a gap whatever its residual (ezc3d writes gaps as
/// NaN with residual 0); a residual of -0.0 is a zero residual.
#[test]
fn non_finite_coordinates_are_gaps() {
    let points = vec![vec![Some([f32::NAN, 1.0, 2.0]), Some([1.0, 2.0, 3.0])]];
    let bytes = GuideFile::new(&["A", "B"], points).bytes();
    let t = read_c3d_bytes(&bytes, &no_map(), Path::new("n.c3d")).unwrap();
    assert_eq!(t.get("A", 0), None);
    assert_eq!(t.get("B", 0), Some(Point::new(1.0, 2.0, 3.0)));
    let mut b = bytes.clone();
    let ds = le_u16(&b, 16) as usize;
    let residual = BLOCK * (ds - 1) + 16 + 12;
    b[residual..residual + 4].copy_from_slice(&(-0.0f32).to_le_bytes());
    let t = read_c3d_bytes(&b, &no_map(), Path::new("n.c3d")).unwrap();
    assert_eq!(t.get("B", 0), Some(Point::new(1.0, 2.0, 3.0)));
    b[residual..residual + 4].copy_from_slice(&(-1e-3f32).to_le_bytes());
    let t = read_c3d_bytes(&b, &no_map(), Path::new("n.c3d")).unwrap();
    assert_eq!(t.get("B", 0), None);
}

/// Every way other writers give more than 65,535 frames: a float `POINT:FRAMES`, an integer one
/// stuck at 65,535 with the count in `TRIAL:ACTUAL_*_FIELD` (whatever the first frame's number)
/// or in `POINT:LONG_FRAMES`. One marker whose x and y give its frame index (within what a
/// 16-bit count of 0.5 mm holds), so that a frame lost or shifted anywhere shows.
#[test]
fn frame_counts_beyond_16_bits_from_other_writers() {
    let frames = 70_001;
    let points: Vec<Vec<Option<[f32; 3]>>> = (0..frames)
        .map(|f| {
            let (x, y) = ((f % 30_000) as f32 * 0.5, (f / 30_000) as f32);
            vec![(f % 1000 != 9).then_some([x, y, 2.0])]
        })
        .collect();
    let base = || GuideFile::new(&["A"], points.clone());
    let files = [
        GuideFile {
            frames: Frames::Float,
            ..base()
        },
        GuideFile {
            trial: Some((1, frames as u32)),
            ..base()
        },
        GuideFile {
            trial: Some((65_000, 65_000 + frames as u32 - 1)),
            ..base()
        },
        GuideFile {
            long_frames: Some(frames as f32),
            ..base()
        },
        GuideFile {
            proc: Proc::Mips,
            scale: 0.5,
            analog: (2, 2),
            trial: Some((1, frames as u32)),
            ..base()
        },
    ];
    for (i, file) in files.iter().enumerate() {
        let t = read_c3d_bytes(&file.bytes(), &no_map(), Path::new("long.c3d"))
            .unwrap_or_else(|e| panic!("file {i}: {e}"));
        assert_reads_as(&t, &points, 1.0);
    }
    // Without any of them the integer POINT:FRAMES (65,535) is all there is.
    let t = read_c3d_bytes(&base().bytes(), &no_map(), Path::new("long.c3d")).unwrap();
    assert_eq!(t.n_frames(), 65_535);
}

#[test]
fn labels_continue_past_255() {
    let labels: Vec<String> = (0..300).map(|m| format!("M{m}")).collect();
    let names: Vec<&str> = labels.iter().map(String::as_str).collect();
    let points = guide_points(300, 3);
    let bytes = GuideFile::new(&names, points.clone()).bytes();
    let t = read_c3d_bytes(&bytes, &no_map(), Path::new("many.c3d")).unwrap();
    assert_eq!(t.labels, labels);
    assert_reads_as(&t, &points, 1.0);
}

/// The writer continues labels in `POINT:LABELS2` past 255 markers and reads them back.
#[test]
fn writer_labels_past_255_round_trip() {
    let labels: Vec<String> = (0..300).map(|m| format!("Marker{m:03}")).collect();
    let names: Vec<&str> = labels.iter().map(String::as_str).collect();
    let t = sample(&names, 12);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("many.c3d");
    write_c3d(&path, &t).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let params = params_of(&bytes);
    assert_eq!(params.get("POINT", "LABELS").unwrap().dims, [9, 255]);
    assert_eq!(params.get("POINT", "LABELS2").unwrap().dims, [9, 45]);
    assert_eq!(params.get("POINT", "DESCRIPTIONS2").unwrap().dims, [1, 45]);
    assert_eq!(
        params.get("POINT", "USED").unwrap().ints(Proc::Intel),
        Some(vec![300])
    );
    let back = read_c3d(&path, &no_map()).unwrap();
    assert_same_within_f32(&t, &back);
}

/// Parameters that contradict the header are named, with the header word they contradict.
#[test]
fn contradicting_parameters_are_named() {
    let file = GuideFile {
        analog: (2, 4),
        ..GuideFile::new(&["A", "B"], guide_points(2, 10))
    };
    let good = file.bytes();
    let params = params_of(&good);
    let patch = |group: &str, name: &str, value: &[u8]| {
        let mut b = good.clone();
        let at = BLOCK + params.get(group, name).unwrap().at;
        b[at..at + value.len()].copy_from_slice(value);
        read_err(&b)
    };
    let e = patch("ANALOG", "RATE", &1000f32.to_le_bytes());
    assert!(
        e.contains("ANALOG:RATE (1000 Hz)") && e.contains("word 10, 4"),
        "{e}"
    );
    let e = patch("ANALOG", "USED", &3i16.to_le_bytes());
    assert!(
        e.contains("ANALOG:USED (3)") && e.contains("word 3, 8"),
        "{e}"
    );
    let e = patch("POINT", "DATA_START", &7i16.to_le_bytes());
    assert!(
        e.contains("POINT:DATA_START (7)") && e.contains("word 9"),
        "{e}"
    );
    let e = patch("POINT", "SCALE", &0.1f32.to_le_bytes());
    assert!(e.contains("POINT:SCALE"), "{e}");
    // The frame count in a TRIAL field past the data.
    let long = GuideFile {
        trial: Some((1, 100)),
        ..GuideFile::new(&["A", "B"], guide_points(2, 10))
    };
    let e = read_err(&long.bytes());
    assert!(e.contains("truncated") && e.contains("100 frames"), "{e}");
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

    // An empty label cannot be named: that marker is dropped.
    let bytes = GuideFile::new(&["A", "", "C"], guide_points(3, 4)).bytes();
    let t = read_c3d_bytes(&bytes, &no_map(), &path).unwrap();
    assert_eq!(t.labels, ["A", "C"]);
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

/// An integer file with analog samples: the other layout the mutation tests cover.
fn valid_integer_file() -> &'static [u8] {
    static BYTES: OnceLock<Vec<u8>> = OnceLock::new();
    BYTES.get_or_init(|| {
        GuideFile {
            scale: 0.5,
            analog: (2, 3),
            ..GuideFile::new(&["A", "B", "C"], guide_points(3, 40))
        }
        .bytes()
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
    // An unknown processor type.
    let mut b = good.to_vec();
    b[BLOCK + 3] = 87;
    assert!(read_err(&b).contains("processor type 87"));
}

/// Frame counts past the header's 16 bits: written as the C3D community asks and read back
/// exactly.
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
        let params = params_of(&bytes);
        let words = |name: &str| {
            let v = params
                .get("TRIAL", name)
                .unwrap()
                .ints(Proc::Intel)
                .unwrap();
            v[0] as u16 as usize + ((v[1] as u16 as usize) << 16)
        };
        let header_last = le_u16(&bytes, 8) as usize;
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
        std::fs::remove_file(&path).unwrap();
    }
}

/// A file as another writer makes it past 65,535 frames: an integer POINT:FRAMES stuck at
/// 65,535, no LONG_FRAMES, and the count only in TRIAL:ACTUAL_*_FIELD.
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
    let params = params_of(&bytes);
    // LONG_FRAMES renamed out of the way, POINT:FRAMES a float 65,535.
    let long = params.get("POINT", "LONG_FRAMES").unwrap();
    // Before the data: offset word, type, dimension count and one dimension.
    let name_at = BLOCK + long.at - 5 - "LONG_FRAMES".len();
    assert_eq!(&bytes[name_at..name_at + 11], b"LONG_FRAMES");
    bytes[name_at..name_at + 11].copy_from_slice(b"XLONG_FRAME");
    let at = BLOCK + params.get("POINT", "FRAMES").unwrap().at;
    bytes[at..at + 4].copy_from_slice(&65_535f32.to_le_bytes());
    let back = read_c3d_bytes(&bytes, &no_map(), &path).unwrap();
    assert_eq!(back.n_frames(), frames);
    assert_eq!(back.positions, t.positions);
    // Without the TRIAL fields too, POINT:FRAMES is all there is.
    let start = BLOCK + params.get("TRIAL", "ACTUAL_START_FIELD").unwrap().at;
    bytes[start - 5 - 18..start - 5].copy_from_slice(b"XACTUAL_START_FIEL");
    let back = read_c3d_bytes(&bytes, &no_map(), &path).unwrap();
    assert_eq!(back.n_frames(), 65_535);
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
    // More labels than the 255 blocks of a parameter section hold.
    let labels: Vec<String> = (0..4000).map(|m| format!("{m:0>40}")).collect();
    let names: Vec<&str> = labels.iter().map(String::as_str).collect();
    let e = write_c3d(&path, &sample(&names, 1))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("4000 markers") && e.contains("parameter blocks"),
        "{e}"
    );
    assert!(!path.exists());
}

/// Outcome of one read of mutated bytes: an error or a self-consistent result (a panic fails the
/// test).
fn check_mutant(bytes: &[u8]) {
    if let Ok(t) = read_c3d_bytes(bytes, &no_map(), Path::new("m.c3d")) {
        assert!(t.n_frames() >= 1 && !t.labels.is_empty());
        assert!(t.positions.iter().all(|p| p.len() == t.n_frames()));
        // Every sample came from 16 (float) or 8 (integer) bytes of the input.
        assert!(8 * t.n_frames() * t.labels.len() <= bytes.len());
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn truncated_files_never_panic(len in 0usize..3000, integer in any::<bool>()) {
        let good = if integer { valid_integer_file() } else { valid_file() };
        check_mutant(&good[..len.min(good.len())]);
    }

    #[test]
    fn mutated_structure_never_panics(
        edits in proptest::collection::vec((0usize..1536, any::<u8>()), 1..8),
        integer in any::<bool>()
    ) {
        let mut b = if integer { valid_integer_file() } else { valid_file() }.to_vec();
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
