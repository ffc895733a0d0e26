//! The byte-level pieces the C3D reader and writer share: the block size, the processor types
//! (byte order and float encoding) and the parameter section (user guide chapter 4).

/// C3D block size (user guide chapter 2: the file is a sequence of 512-byte blocks).
pub(super) const BLOCK: usize = 512;

/// The processor type of user guide 4.1 (parameter section byte 4 = 83 + type): byte order and
/// float encoding of every number in the file, header included.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Proc {
    /// Little-endian integers, IEEE floats.
    Intel,
    /// Little-endian integers, VAX F floats.
    Dec,
    /// Big-endian integers, IEEE floats.
    Mips,
}

/// Parameter section byte 4 of a file written by an Intel processor (the writer's choice).
pub(super) const INTEL_BYTE: u8 = 84;

impl Proc {
    pub(super) fn from_byte(b: u8) -> Option<Proc> {
        match b {
            INTEL_BYTE => Some(Proc::Intel),
            85 => Some(Proc::Dec),
            86 => Some(Proc::Mips),
            _ => None,
        }
    }

    pub(super) fn u16(self, b: [u8; 2]) -> u16 {
        match self {
            Proc::Mips => u16::from_be_bytes(b),
            Proc::Intel | Proc::Dec => u16::from_le_bytes(b),
        }
    }

    pub(super) fn i16(self, b: [u8; 2]) -> i16 {
        self.u16(b) as i16
    }

    pub(super) fn f32(self, b: [u8; 4]) -> f32 {
        match self {
            Proc::Intel => f32::from_le_bytes(b),
            Proc::Mips => f32::from_be_bytes(b),
            Proc::Dec => vax_f32(b),
        }
    }
}

/// A VAX F float: two little-endian 16-bit words, the first holding the sign, an exponent biased
/// by 128 and the top of the fraction, read as 0.1f x 2^(e - 128) = 1.f x 2^(e - 129). Swapping
/// the words gives IEEE's bit layout; only the exponent's meaning differs. An exponent of 0 is
/// zero, or with the sign set the "reserved operand", which has no value (NaN here).
fn vax_f32(b: [u8; 4]) -> f32 {
    let bits = u32::from_le_bytes([b[2], b[3], b[0], b[1]]);
    let negative = bits >> 31 == 1;
    let exponent = ((bits >> 23) & 0xff) as i32;
    if exponent == 0 {
        return if negative { f32::NAN } else { 0.0 };
    }
    let mantissa = 1.0 + f64::from(bits & 0x7f_ffff) / f64::from(1u32 << 23);
    let magnitude = mantissa * 2f64.powi(exponent - 129);
    (if negative { -magnitude } else { magnitude }) as f32
}

/// Parameter types (user guide 4.3): -1 character, 1 byte, 2 16-bit integer, 4 float.
pub(super) const CHAR: i8 = -1;
pub(super) const BYTE: i8 = 1;
pub(super) const INT: i8 = 2;
pub(super) const FLOAT: i8 = 4;

/// One parameter of the parameter section (user guide 4.3).
#[derive(Debug)]
pub(super) struct Param {
    /// Upper case, as are all names here (the user guide's names are case-insensitive).
    pub(super) group: String,
    pub(super) name: String,
    pub(super) kind: i8,
    /// Offset of `data` in the parameter section (tests patch values there).
    #[cfg_attr(not(test), allow(dead_code))]
    pub(super) at: usize,
    /// The dimensions as written; none for a scalar.
    pub(super) dims: Vec<usize>,
    pub(super) data: Vec<u8>,
}

impl Param {
    pub(super) fn ints(&self, p: Proc) -> Option<Vec<i16>> {
        (self.kind == INT).then(|| {
            self.data
                .chunks_exact(2)
                .map(|c| p.i16([c[0], c[1]]))
                .collect()
        })
    }

    pub(super) fn floats(&self, p: Proc) -> Option<Vec<f32>> {
        (self.kind == FLOAT).then(|| {
            self.data
                .chunks_exact(4)
                .map(|c| p.f32([c[0], c[1], c[2], c[3]]))
                .collect()
        })
    }

    /// The character data as strings of `dims[0]` characters (Latin-1), trimmed of blanks and
    /// NULs: one string for up to one dimension, `dims[1]` for two; `None` for more or another
    /// type.
    pub(super) fn strings(&self) -> Option<Vec<String>> {
        if self.kind != CHAR || self.dims.len() > 2 {
            return None;
        }
        let width = self.dims.first().copied().unwrap_or(1);
        if width == 0 {
            return Some(vec![String::new(); self.dims.get(1).copied().unwrap_or(1)]);
        }
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

    /// The first value as a count: an integer read unsigned (counts up to 65,535 are written as
    /// 16-bit words), a float rounded toward zero (negative and NaN give 0).
    pub(super) fn count(&self, p: Proc) -> Option<usize> {
        match self.kind {
            INT => self.ints(p)?.first().map(|&v| v as u16 as usize),
            FLOAT => self.floats(p)?.first().map(|&v| v as usize),
            _ => None,
        }
    }
}

/// The parameters of a file.
#[derive(Debug)]
pub(super) struct Params {
    list: Vec<Param>,
}

impl Params {
    /// The last parameter `GROUP:NAME` (a later duplicate overrides an earlier one).
    pub(super) fn get(&self, group: &str, name: &str) -> Option<&Param> {
        self.list
            .iter()
            .rev()
            .find(|p| p.group == group && p.name == name)
    }
}

/// Walk the parameter section (user guide 4.2, 4.3): records start at byte 4, each a name length
/// and an id (negative: a group, positive: a parameter of group -id), the name, and a 16-bit
/// offset from that word to the next record. A zero id, a zero offset or the end of the section
/// ends the walk. Every read is bounds-checked and every length checked against the section
/// before it sizes anything; the offset only moves forward, so the walk ends.
pub(super) fn walk_parameters(section: &[u8], proc: Proc) -> Result<Params, String> {
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
    let byte = |at: usize, what: &str| slice(at, 1, what).map(|s| s[0]);
    let mut groups: Vec<(u8, String)> = Vec::new();
    let mut raw: Vec<(u8, Param)> = Vec::new();
    let mut index = 4;
    while index + 1 < section.len() {
        let id = section[index + 1] as i8;
        if id == 0 {
            break;
        }
        // A negative name length marks a locked record; the length is its magnitude.
        let name_len = (section[index] as i8).unsigned_abs() as usize;
        let mut i = index + 2;
        let name = latin1(slice(i, name_len, "name")?).to_ascii_uppercase();
        i += name_len;
        let off = slice(i, 2, "offset")?;
        let offset = proc.u16([off[0], off[1]]) as usize;
        let next = i + offset;
        i += 2;
        if id < 0 {
            let desc_len = byte(i, "description length")? as usize;
            slice(i + 1, desc_len, "description")?;
            groups.push((id.unsigned_abs(), name));
        } else {
            let kind = byte(i, "type")? as i8;
            let size: usize = match kind {
                CHAR | BYTE => 1,
                INT => 2,
                FLOAT => 4,
                _ => return Err(bad(&format!("parameter {name} has type {kind}"), i)),
            };
            i += 1;
            let ndims = byte(i, "dimension count")? as usize;
            i += 1;
            let dims: Vec<usize> = slice(i, ndims, "dimensions")?
                .iter()
                .map(|&d| d as usize)
                .collect();
            i += ndims;
            // Bounded by the section length at every step: 255 dimensions of 255 overflow.
            let len = dims
                .iter()
                .try_fold(size, |acc, &d| {
                    acc.checked_mul(d).filter(|&l| l <= section.len())
                })
                .ok_or_else(|| bad(&format!("parameter {name} is larger than the section"), i))?;
            let data = slice(i, len, "data")?.to_vec();
            i += len;
            let desc_len = byte(i, "description length")? as usize;
            slice(i + 1, desc_len, "description")?;
            let param = Param {
                group: String::new(),
                name,
                kind,
                at: i - len,
                dims,
                data,
            };
            raw.push((id.unsigned_abs(), param));
        }
        if offset == 0 {
            break;
        }
        index = next;
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
    Ok(Params { list })
}

/// Bytes as Latin-1 text (every byte a character, so no input is rejected).
fn latin1(bytes: &[u8]) -> String {
    bytes.iter().map(|&b| b as char).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// VAX F constants from the format's definition: 1.0 is 0x4080 0x0000 (exponent 129,
    /// fraction 0), 2.5 is 0x4120 0x0000, -0.75 is 0xC040 0x0000; each word little-endian.
    #[test]
    fn vax_floats_decode() {
        assert_eq!(Proc::Dec.f32([0x80, 0x40, 0x00, 0x00]), 1.0);
        assert_eq!(Proc::Dec.f32([0x20, 0x41, 0x00, 0x00]), 2.5);
        assert_eq!(Proc::Dec.f32([0x40, 0xc0, 0x00, 0x00]), -0.75);
        // 1 + 2^-23: the last fraction bit lives in the second word.
        assert_eq!(Proc::Dec.f32([0x80, 0x40, 0x01, 0x00]), 1.0 + f32::EPSILON);
        assert_eq!(Proc::Dec.f32([0, 0, 0, 0]), 0.0);
        assert!(Proc::Dec.f32([0x00, 0x80, 0x00, 0x00]).is_nan());
        // The largest exponent is a number, not an infinity.
        assert!(Proc::Dec.f32([0xff, 0x7f, 0xff, 0xff]).is_finite());
    }

    #[test]
    fn byte_orders() {
        assert_eq!(Proc::Intel.u16([0x34, 0x12]), 0x1234);
        assert_eq!(Proc::Dec.u16([0x34, 0x12]), 0x1234);
        assert_eq!(Proc::Mips.u16([0x12, 0x34]), 0x1234);
        assert_eq!(Proc::Mips.i16([0xff, 0xfe]), -2);
        assert_eq!(Proc::Mips.f32([0x3f, 0x80, 0, 0]), 1.0);
        assert_eq!(Proc::Intel.f32([0, 0, 0x80, 0x3f]), 1.0);
    }

    #[test]
    fn walk_reads_groups_parameters_and_stops() {
        // Group 1 "point", then POINT:USED = 3 and POINT:LABELS ["AB", "C"], lower case names
        // and a locked (negative length) record, then a zero offset ends the walk before junk.
        let mut s = vec![1, 0x50, 1, INTEL_BYTE];
        s.extend([5, (-1i8) as u8]);
        s.extend(b"point");
        s.extend(3u16.to_le_bytes());
        s.push(0);
        s.extend([(-4i8) as u8, 1]);
        s.extend(b"Used");
        s.extend(7u16.to_le_bytes());
        s.extend([INT as u8, 0]);
        s.extend(3i16.to_le_bytes());
        s.push(0);
        s.extend([6, 1]);
        s.extend(b"LABELS");
        s.extend(0u16.to_le_bytes());
        s.extend([CHAR as u8, 2, 2, 2]);
        s.extend(b"ABC ");
        s.extend([2, b'h', b'i']);
        s.extend([4, 1, b'J', b'U', b'N', b'K', 0xff, 0xff, 0x7f]);
        let p = walk_parameters(&s, Proc::Intel).unwrap();
        let used = p.get("POINT", "USED").unwrap();
        assert_eq!(used.count(Proc::Intel), Some(3));
        assert!(used.dims.is_empty());
        let labels = p.get("POINT", "LABELS").unwrap();
        assert_eq!(labels.strings().unwrap(), ["AB", "C"]);
        assert_eq!(&s[labels.at..labels.at + 4], b"ABC ");
        assert!(p.get("POINT", "JUNK").is_none());
        // Cut anywhere inside a record: an error, never a panic.
        for n in 0..s.len() - 9 {
            let _ = walk_parameters(&s[..n], Proc::Intel);
        }
        assert!(walk_parameters(&s[..30], Proc::Intel)
            .unwrap_err()
            .contains("parameter section corrupt"));
    }
}
