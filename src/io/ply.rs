//! PLY (Stanford polygon file format), ASCII and binary, little- and big-endian.
//!
//! Format reference: Greg Turk, "The PLY Polygon File Format" (1994), as documented by Paul
//! Bourke: a text header (`ply`, `format`, `comment`/`obj_info`, `element <name> <count>`,
//! `property <type> <name>`, `property list <count type> <item type> <name>`, `end_header`)
//! followed by the elements' rows in header order, as whitespace-separated text or packed
//! binary. Types: `char uchar short ushort int uint float double` and their sized aliases
//! `int8 uint8 int16 uint16 int32 uint32 float32 float64`.
//!
//! Read: `vertex` `x y z` (any numeric type, any order among other properties, which are
//! skipped by type), optional `red green blue` as `uchar`, and `face` `vertex_indices` (or
//! `vertex_index`) lists of any integer type, fan-triangulated. Other elements are skipped.
//! Written: binary little-endian, `float` or `double` positions, optional `uchar` colours,
//! `list uchar int vertex_indices`.

use super::atomic::{read_bytes, write_atomic};
use super::obj::check_mesh;
use super::Units;
use crate::error::{Error, Result};
use crate::geometry::{Point, TriMesh};
use std::path::Path;

/// A mesh read from PLY, with its per-vertex colours when the file has them.
#[derive(Clone, Debug, PartialEq)]
pub struct PlyMesh {
    /// The triangle mesh, in mm.
    pub mesh: TriMesh,
    /// One `[red, green, blue]` per vertex when the vertex element has `uchar red green blue`.
    pub colors: Option<Vec<[u8; 3]>>,
}

/// Read a PLY file whose coordinates are in `units`; returns the mesh in millimetres.
pub fn read_ply(path: &Path, units: Units) -> Result<PlyMesh> {
    let bytes = read_bytes(path)?;
    read_ply_bytes(&bytes, units, path)
}

/// Parse PLY bytes (see the module doc for what is read); `label` names the source in errors.
///
/// Every element count is checked against the bytes after the header before anything is
/// allocated (each binary row needs at least its scalars and list counts; each ASCII value
/// at least two characters), and every list length against the bytes left. Header errors name
/// the header line; body errors name the element row (and, for ASCII, the line). Polygons are
/// fan-triangulated `(0, i, i+1)`; a face with fewer than three vertices, a repeated vertex in
/// a triangle or an index out of range is an error, as is a non-finite coordinate.
pub(crate) fn read_ply_bytes(bytes: &[u8], units: Units, label: &Path) -> Result<PlyMesh> {
    let err = |msg: String| Error::input(label, msg);
    let header = parse_header(bytes).map_err(err)?;
    let body = &bytes[header.body_start..];

    let vi = header
        .elements
        .iter()
        .position(|e| e.name == "vertex")
        .ok_or_else(|| err("no 'vertex' element in the header".into()))?;
    let fi = header
        .elements
        .iter()
        .position(|e| e.name == "face")
        .ok_or_else(|| {
            err("no 'face' element in the header (a point cloud); a triangle mesh is needed".into())
        })?;
    let vroles = vertex_roles(&header.elements[vi]).map_err(err)?;
    let froles = face_roles(&header.elements[fi]).map_err(err)?;
    let has_color = [Role::R, Role::G, Role::B]
        .iter()
        .all(|r| vroles.contains(r));
    check_sizes(&header, body.len()).map_err(err)?;

    let n_vertices = usize::try_from(header.elements[vi].count)
        .map_err(|_| err("vertex count does not fit in memory".into()))?;
    let mut vertices: Vec<Point> = Vec::with_capacity(n_vertices);
    let mut colors: Vec<[u8; 3]> = Vec::with_capacity(if has_color { n_vertices } else { 0 });
    let mut faces: Vec<[usize; 3]> = Vec::new();
    let scale = units.to_mm();
    let mut src = Body::new(body, header.format, header.body_line);
    let mut poly: Vec<usize> = Vec::new();

    for (ei, el) in header.elements.iter().enumerate() {
        if el.props.is_empty() {
            continue;
        }
        for row in 0..el.count {
            let item = |at: String, msg: String| {
                Error::input(label, format!("{at}{} {row}: {msg}", el.name))
            };
            let mut xyz = [0.0f64; 3];
            let mut rgb = [0u8; 3];
            for (pi, prop) in el.props.iter().enumerate() {
                let role = if ei == vi {
                    vroles[pi]
                } else if ei == fi {
                    froles[pi]
                } else {
                    Role::Skip
                };
                match *prop {
                    Prop::Scalar { ty, .. } => {
                        let v = src.scalar(ty).map_err(|m| item(src.line_prefix(), m))?;
                        match role {
                            Role::X => xyz[0] = v,
                            Role::Y => xyz[1] = v,
                            Role::Z => xyz[2] = v,
                            Role::R => rgb[0] = v as u8,
                            Role::G => rgb[1] = v as u8,
                            Role::B => rgb[2] = v as u8,
                            _ => {}
                        }
                    }
                    Prop::List {
                        count, item: ity, ..
                    } => {
                        let n = src.scalar(count).map_err(|m| item(src.line_prefix(), m))?;
                        if n < 0.0 {
                            return Err(item(
                                src.line_prefix(),
                                format!("list length {n} is negative"),
                            ));
                        }
                        let n = n as u64;
                        src.check_list(n, ity)
                            .map_err(|m| item(src.line_prefix(), m))?;
                        if role != Role::Indices {
                            for _ in 0..n {
                                src.scalar(ity).map_err(|m| item(src.line_prefix(), m))?;
                            }
                            continue;
                        }
                        poly.clear();
                        for _ in 0..n {
                            let v = src.scalar(ity).map_err(|m| item(src.line_prefix(), m))?;
                            if v < 0.0 || v >= n_vertices as f64 {
                                return Err(item(
                                    src.line_prefix(),
                                    format!("names vertex {v}, but the file has {n_vertices}"),
                                ));
                            }
                            poly.push(v as usize);
                        }
                        if poly.len() < 3 {
                            return Err(item(
                                src.line_prefix(),
                                format!("has {} vertices; a face needs at least 3", poly.len()),
                            ));
                        }
                        for i in 1..poly.len() - 1 {
                            let t = [poly[0], poly[i], poly[i + 1]];
                            if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
                                return Err(item(
                                    src.line_prefix(),
                                    format!(
                                    "repeats a vertex in triangle {t:?}; remove degenerate faces"
                                ),
                                ));
                            }
                            faces.push(t);
                        }
                    }
                }
            }
            if ei == vi {
                if !xyz.iter().all(|c| c.is_finite()) {
                    return Err(item(
                        src.line_prefix(),
                        format!("non-finite coordinate {xyz:?}"),
                    ));
                }
                vertices.push(Point::new(xyz[0] * scale, xyz[1] * scale, xyz[2] * scale));
                if has_color {
                    colors.push(rgb);
                }
            }
        }
    }
    if faces.is_empty() {
        return Err(err("holds no faces; a triangle mesh is needed".into()));
    }
    let mesh = TriMesh::new(vertices, faces).map_err(|e| e.in_file(label))?;
    Ok(PlyMesh {
        mesh,
        colors: has_color.then_some(colors),
    })
}

/// Write `mesh` (mm) as binary little-endian PLY with `float` positions in `units` and, when
/// given, one `uchar` colour per vertex. Positions keep `f32` precision (about 7 digits),
/// enough for display and exchange; use [`write_ply_f64`] where exactness matters.
pub fn write_ply(
    path: &Path,
    mesh: &TriMesh,
    units: Units,
    colors: Option<&[[u8; 3]]>,
) -> Result<()> {
    write_ply_as(path, mesh, units, colors, false)
}

/// [`write_ply`] with `double` positions: reading the file back in the same unit restores
/// every coordinate exactly when `units` is millimetres (reference surfaces, test fixtures).
pub fn write_ply_f64(
    path: &Path,
    mesh: &TriMesh,
    units: Units,
    colors: Option<&[[u8; 3]]>,
) -> Result<()> {
    write_ply_as(path, mesh, units, colors, true)
}

fn write_ply_as(
    path: &Path,
    mesh: &TriMesh,
    units: Units,
    colors: Option<&[[u8; 3]]>,
    double: bool,
) -> Result<()> {
    check_mesh(mesh).map_err(|e| e.in_file(path))?;
    if i32::try_from(mesh.n_vertices()).is_err() {
        return Err(Error::input(
            path,
            format!("{} vertices exceed PLY's int indices", mesh.n_vertices()),
        ));
    }
    if let Some(c) = colors {
        if c.len() != mesh.n_vertices() {
            return Err(Error::input(
                path,
                format!(
                    "{} colours given for {} vertices; give one colour per vertex",
                    c.len(),
                    mesh.n_vertices()
                ),
            ));
        }
    }
    let s = 1.0 / units.to_mm();
    if !double {
        if let Some(i) = mesh
            .vertices
            .iter()
            .position(|p| !(p * s).iter().all(|&c| (c as f32).is_finite()))
        {
            return Err(Error::input(
                path,
                format!("vertex {i} does not fit a 32-bit float in {units}"),
            ));
        }
    }
    let ty = if double { "double" } else { "float" };
    let mut header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment ergohand mesh, units: {units}\n\
         element vertex {}\nproperty {ty} x\nproperty {ty} y\nproperty {ty} z\n",
        mesh.n_vertices()
    );
    if colors.is_some() {
        header.push_str("property uchar red\nproperty uchar green\nproperty uchar blue\n");
    }
    header.push_str(&format!(
        "element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        mesh.n_faces()
    ));
    write_atomic(path, |w| {
        w.write_all(header.as_bytes())?;
        for (i, p) in mesh.vertices.iter().enumerate() {
            let q = p * s;
            for c in q.iter() {
                if double {
                    w.write_all(&c.to_le_bytes())?;
                } else {
                    w.write_all(&(*c as f32).to_le_bytes())?;
                }
            }
            if let Some(c) = colors {
                w.write_all(&c[i])?;
            }
        }
        for f in &mesh.faces {
            let mut rec = [3u8; 13];
            for (k, &v) in f.iter().enumerate() {
                rec[1 + 4 * k..5 + 4 * k].copy_from_slice(&(v as i32).to_le_bytes());
            }
            w.write_all(&rec)?;
        }
        Ok(())
    })
}

/// A PLY scalar type.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(s: &str) -> Option<Self> {
        Some(match s {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    fn is_int(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }

    /// Inclusive range of an integer type.
    fn range(self) -> (i64, i64) {
        match self {
            Scalar::I8 => (i8::MIN as i64, i8::MAX as i64),
            Scalar::U8 => (0, u8::MAX as i64),
            Scalar::I16 => (i16::MIN as i64, i16::MAX as i64),
            Scalar::U16 => (0, u16::MAX as i64),
            Scalar::I32 => (i32::MIN as i64, i32::MAX as i64),
            Scalar::U32 => (0, u32::MAX as i64),
            Scalar::F32 | Scalar::F64 => (i64::MIN, i64::MAX),
        }
    }
}

#[derive(Clone, Debug)]
enum Prop {
    Scalar {
        name: String,
        ty: Scalar,
    },
    List {
        name: String,
        count: Scalar,
        item: Scalar,
    },
}

impl Prop {
    fn name(&self) -> &str {
        match self {
            Prop::Scalar { name, .. } | Prop::List { name, .. } => name,
        }
    }
}

#[derive(Clone, Debug)]
struct Element {
    name: String,
    count: u64,
    props: Vec<Prop>,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Format {
    Ascii,
    Little,
    Big,
}

#[derive(Debug)]
struct Header {
    format: Format,
    elements: Vec<Element>,
    /// Byte offset of the first row.
    body_start: usize,
    /// 1-based line number of the first body line (for ASCII error messages).
    body_line: usize,
}

/// Parse the header up to and including the `end_header` line. Errors name the header line.
fn parse_header(bytes: &[u8]) -> std::result::Result<Header, String> {
    let mut pos = 0usize;
    let mut line_no = 0usize;
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        if pos >= bytes.len() {
            return Err(if line_no == 0 {
                "not a PLY file: it is empty".into()
            } else {
                format!("truncated header: no 'end_header' after {line_no} lines")
            });
        }
        let end = bytes[pos..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(bytes.len(), |i| pos + i);
        let raw = &bytes[pos..end];
        pos = (end + 1).min(bytes.len());
        line_no += 1;
        let at = |msg: String| format!("header line {line_no}: {msg}");
        let text = std::str::from_utf8(raw)
            .ok()
            .filter(|s| s.is_ascii())
            .ok_or_else(|| {
                if line_no == 1 {
                    "not a PLY file: it does not start with 'ply'".to_string()
                } else {
                    at("not ASCII text (is the header cut short?)".into())
                }
            })?;
        let words: Vec<&str> = text.split_ascii_whitespace().collect();
        if line_no == 1 {
            if words != ["ply"] {
                return Err("not a PLY file: it does not start with 'ply'".into());
            }
            continue;
        }
        match words.as_slice() {
            [] => {}
            ["comment", ..] | ["obj_info", ..] => {}
            ["format", f, _version] => {
                format = Some(match *f {
                    "ascii" => Format::Ascii,
                    "binary_little_endian" => Format::Little,
                    "binary_big_endian" => Format::Big,
                    other => return Err(at(format!("unknown format '{other}'"))),
                })
            }
            ["element", name, count] => {
                let count = count
                    .parse::<u64>()
                    .map_err(|_| at(format!("element '{name}' count '{count}' is not a count")))?;
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    props: Vec::new(),
                });
            }
            ["property", "list", count, item, name] => {
                let el = elements
                    .last_mut()
                    .ok_or_else(|| at(format!("property '{name}' before any element")))?;
                let count = Scalar::parse(count).filter(|c| c.is_int()).ok_or_else(|| {
                    at(format!(
                        "list '{name}' count type '{count}' is not an integer type"
                    ))
                })?;
                let item = Scalar::parse(item)
                    .ok_or_else(|| at(format!("list '{name}' has unknown item type '{item}'")))?;
                el.props.push(Prop::List {
                    name: name.to_string(),
                    count,
                    item,
                });
            }
            ["property", ty, name] => {
                let el = elements
                    .last_mut()
                    .ok_or_else(|| at(format!("property '{name}' before any element")))?;
                let ty = Scalar::parse(ty)
                    .ok_or_else(|| at(format!("property '{name}' has unknown type '{ty}'")))?;
                el.props.push(Prop::Scalar {
                    name: name.to_string(),
                    ty,
                });
            }
            ["end_header"] => {
                let format =
                    format.ok_or_else(|| at("'end_header' before any 'format' line".into()))?;
                return Ok(Header {
                    format,
                    elements,
                    body_start: pos,
                    body_line: line_no + 1,
                });
            }
            _ => {
                let shown: String = text.trim().chars().take(60).collect();
                return Err(at(format!("cannot read '{shown}'")));
            }
        }
    }
}

/// What a property means to the reader.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Role {
    X,
    Y,
    Z,
    R,
    G,
    B,
    Indices,
    Skip,
}

fn vertex_roles(el: &Element) -> std::result::Result<Vec<Role>, String> {
    let mut roles = vec![Role::Skip; el.props.len()];
    for (axis, role) in [("x", Role::X), ("y", Role::Y), ("z", Role::Z)] {
        let i = el
            .props
            .iter()
            .position(|p| p.name() == axis)
            .ok_or_else(|| format!("vertex element has no '{axis}' property"))?;
        if !matches!(el.props[i], Prop::Scalar { .. }) {
            return Err(format!("vertex property '{axis}' is a list, not a number"));
        }
        roles[i] = role;
    }
    let rgb: Vec<Option<usize>> = ["red", "green", "blue"]
        .iter()
        .map(|c| {
            el.props.iter().position(
                |p| matches!(p, Prop::Scalar { name, ty: Scalar::U8 } if name.as_str() == *c),
            )
        })
        .collect();
    if let [Some(r), Some(g), Some(b)] = rgb[..] {
        roles[r] = Role::R;
        roles[g] = Role::G;
        roles[b] = Role::B;
    }
    Ok(roles)
}

fn face_roles(el: &Element) -> std::result::Result<Vec<Role>, String> {
    let i = el
        .props
        .iter()
        .position(|p| p.name() == "vertex_indices" || p.name() == "vertex_index")
        .ok_or("face element has no 'vertex_indices' (or 'vertex_index') list")?;
    match el.props[i] {
        Prop::List { item, .. } if item.is_int() => {}
        _ => {
            return Err(format!(
                "face property '{}' must be a list of an integer type",
                el.props[i].name()
            ))
        }
    }
    let mut roles = vec![Role::Skip; el.props.len()];
    roles[i] = Role::Indices;
    Ok(roles)
}

/// Error unless the body can hold every element's rows: in binary each row needs its scalars
/// and list counts, in ASCII each value needs at least one character and a separator. Run
/// before allocating, so a header claiming billions of rows costs nothing.
fn check_sizes(header: &Header, body_len: usize) -> std::result::Result<(), String> {
    let mut need: u128 = 0;
    for el in &header.elements {
        let row: u128 = match header.format {
            Format::Ascii => 2 * el.props.len() as u128,
            _ => el
                .props
                .iter()
                .map(|p| match p {
                    Prop::Scalar { ty, .. } => ty.size() as u128,
                    Prop::List { count, .. } => count.size() as u128,
                })
                .sum(),
        };
        need += row * el.count as u128;
        // ASCII: the last value needs no separator.
        let slack = u128::from(header.format == Format::Ascii);
        if need > body_len as u128 + slack {
            return Err(format!(
                "truncated: header says {} {} rows (with the elements before them at least \
                 {need} bytes), but the data after the header holds {body_len} bytes",
                el.count, el.name
            ));
        }
    }
    Ok(())
}

/// A cursor over the rows, binary or ASCII.
struct Body<'a> {
    bytes: &'a [u8],
    pos: usize,
    format: Format,
    /// Current line (ASCII only).
    line: usize,
}

impl<'a> Body<'a> {
    fn new(bytes: &'a [u8], format: Format, first_line: usize) -> Self {
        Body {
            bytes,
            pos: 0,
            format,
            line: first_line,
        }
    }

    fn line_prefix(&self) -> String {
        if self.format == Format::Ascii {
            format!("line {}, ", self.line)
        } else {
            String::new()
        }
    }

    /// Error unless `n` list items of type `ty` can still fit in the bytes left.
    fn check_list(&self, n: u64, ty: Scalar) -> std::result::Result<(), String> {
        let left = (self.bytes.len() - self.pos) as u128;
        let need = match self.format {
            Format::Ascii => n as u128,
            _ => n as u128 * ty.size() as u128,
        };
        if need > left {
            Err(format!(
                "truncated: list of {n} items, but only {left} bytes are left"
            ))
        } else {
            Ok(())
        }
    }

    /// The next value as f64 (exact for every PLY integer type).
    fn scalar(&mut self, ty: Scalar) -> std::result::Result<f64, String> {
        match self.format {
            Format::Ascii => self.ascii(ty),
            f => {
                let n = ty.size();
                let b = self
                    .bytes
                    .get(self.pos..self.pos + n)
                    .ok_or_else(|| "truncated: the file ends inside this row".to_string())?;
                self.pos += n;
                let mut a = [0u8; 8];
                a[..n].copy_from_slice(b);
                if f == Format::Big {
                    a[..n].reverse();
                }
                let w2 = [a[0], a[1]];
                let w4 = [a[0], a[1], a[2], a[3]];
                Ok(match ty {
                    Scalar::I8 => a[0] as i8 as f64,
                    Scalar::U8 => a[0] as f64,
                    Scalar::I16 => i16::from_le_bytes(w2) as f64,
                    Scalar::U16 => u16::from_le_bytes(w2) as f64,
                    Scalar::I32 => i32::from_le_bytes(w4) as f64,
                    Scalar::U32 => u32::from_le_bytes(w4) as f64,
                    Scalar::F32 => f32::from_le_bytes(w4) as f64,
                    Scalar::F64 => f64::from_le_bytes(a),
                })
            }
        }
    }

    fn ascii(&mut self, ty: Scalar) -> std::result::Result<f64, String> {
        let b = self.bytes;
        while self.pos < b.len() && b[self.pos].is_ascii_whitespace() {
            if b[self.pos] == b'\n' {
                self.line += 1;
            }
            self.pos += 1;
        }
        let start = self.pos;
        while self.pos < b.len() && !b[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        let tok = &b[start..self.pos];
        if tok.is_empty() {
            return Err("truncated: the file ends inside this row".into());
        }
        let text = std::str::from_utf8(tok).unwrap_or("");
        let shown = || {
            String::from_utf8_lossy(tok)
                .chars()
                .take(40)
                .collect::<String>()
        };
        if ty.is_int() {
            let (lo, hi) = ty.range();
            match text.parse::<i64>() {
                Ok(v) if (lo..=hi).contains(&v) => Ok(v as f64),
                _ => Err(format!("'{}' is not a {ty:?} integer", shown())),
            }
        } else {
            text.parse::<f64>()
                .map_err(|_| format!("'{}' is not a number", shown()))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::mesh::tests::cuboid;
    use crate::geometry::Vec3;
    use proptest::prelude::*;
    use std::fmt::Write as _;

    fn label() -> &'static Path {
        Path::new("test.ply")
    }

    fn msg(r: Result<PlyMesh>) -> String {
        let s = r.expect_err("expected an error").to_string();
        assert!(
            s.starts_with("test.ply: "),
            "error does not name the file: {s}"
        );
        assert!(!s.contains('\n'), "error is not one line: {s}");
        s
    }

    fn odd_box() -> TriMesh {
        let m = cuboid(0.1, 1.0 / 3.0, std::f64::consts::PI);
        m.transformed(&nalgebra::Isometry3::translation(
            -12.345678901234567,
            1e-9,
            7.0e5,
        ))
    }

    fn colours(n: usize) -> Vec<[u8; 3]> {
        (0..n).map(|i| [i as u8 * 30, 255 - i as u8, 7]).collect()
    }

    #[test]
    fn double_round_trip_is_exact() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.ply");
        let m = odd_box();
        let c = colours(8);
        write_ply_f64(&p, &m, Units::Millimetres, Some(&c)).unwrap();
        let back = read_ply(&p, Units::Millimetres).unwrap();
        assert_eq!(back.mesh, m);
        assert_eq!(back.colors.as_deref(), Some(&c[..]));
        write_ply_f64(&p, &m, Units::Millimetres, None).unwrap();
        let back = read_ply(&p, Units::Millimetres).unwrap();
        assert_eq!(
            back,
            PlyMesh {
                mesh: m,
                colors: None
            }
        );
    }

    #[test]
    fn float_round_trip_to_f32_precision() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("f.ply");
        let m = cuboid(0.1, 1.0 / 3.0, std::f64::consts::PI);
        let c = colours(8);
        write_ply(&p, &m, Units::Millimetres, Some(&c)).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        let header_len = bytes
            .windows(11)
            .position(|w| w == b"end_header\n")
            .unwrap()
            + 11;
        // 8 vertices of 3 floats + 3 bytes, 12 faces of 1 + 3 ints.
        assert_eq!(bytes.len() - header_len, 8 * 15 + 12 * 13);
        let back = read_ply(&p, Units::Millimetres).unwrap();
        assert_eq!(back.mesh.faces, m.faces);
        assert_eq!(back.colors.unwrap(), c);
        for (a, b) in back.mesh.vertices.iter().zip(&m.vertices) {
            assert_eq!(a.map(|x| x as f32), b.map(|x| x as f32));
        }
    }

    #[test]
    fn metres_are_read_as_millimetres() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.ply");
        let m = cuboid(20.0, 30.0, 40.0);
        write_ply_f64(&p, &m, Units::Metres, None).unwrap();
        let back = read_ply(&p, Units::Metres).unwrap().mesh;
        for (a, b) in back.vertices.iter().zip(&m.vertices) {
            assert!((a - b).norm() < 1e-12 * 50.0);
        }
        let cm = read_ply(&p, Units::Centimetres).unwrap().mesh;
        // The same numbers read as centimetres: 0.02 m -> 0.2 mm, so the volume is 0.024 mm³.
        assert!((cm.signed_volume() - 0.024).abs() < 1e-12);
    }

    /// The cube as six quads, written independently of our writer.
    fn cube_quads() -> (Vec<[f64; 3]>, Vec<[usize; 4]>) {
        let v = (0..8)
            .map(|i| [(i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64])
            .collect();
        // Outward counter-clockwise quads of the unit cube with vertex i = (x, y, z) bits.
        let q = vec![
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ];
        (v, q)
    }

    fn check_cube(m: &TriMesh) {
        assert_eq!(m.n_vertices(), 8);
        assert_eq!(m.n_faces(), 12);
        m.check_closed_manifold().unwrap();
        assert!((m.signed_volume() - 1.0).abs() < 1e-12);
        let (v, q) = cube_quads();
        for (p, e) in m.vertices.iter().zip(&v) {
            assert_eq!(p.coords, Vec3::from(*e));
        }
        // Fan triangulation (0, 1, 2), (0, 2, 3) of each quad, in order.
        for (k, f) in q.iter().enumerate() {
            assert_eq!(m.faces[2 * k], [f[0], f[1], f[2]]);
            assert_eq!(m.faces[2 * k + 1], [f[0], f[2], f[3]]);
        }
    }

    #[test]
    fn ascii_with_extra_properties_and_quads() {
        let (v, q) = cube_quads();
        let mut s = String::from(
            "ply\r\nformat ascii 1.0\ncomment made by hand\nobj_info none\n\
             element vertex 8\nproperty float confidence\nproperty double z\n\
             property list uchar int junk\nproperty float x\nproperty float y\n\
             property uchar red\nproperty uchar green\n\
             element face 6\nproperty uchar flags\nproperty list uint8 uint vertex_index\n\
             element edge 1\nproperty int vertex1\nproperty int vertex2\nend_header\n",
        );
        for p in &v {
            writeln!(s, "0.5 {} 2 7 8 {} {} 1 2", p[2], p[0], p[1]).unwrap();
        }
        for f in &q {
            writeln!(s, "0 4 {} {} {} {}", f[0], f[1], f[2], f[3]).unwrap();
        }
        s.push_str("0 1\n");
        let r = read_ply_bytes(s.as_bytes(), Units::Millimetres, label()).unwrap();
        check_cube(&r.mesh);
        // `blue` is missing, so there are no colours.
        assert!(r.colors.is_none());
    }

    #[test]
    fn big_endian_with_mixed_types() {
        let (v, q) = cube_quads();
        let mut b = b"ply\nformat binary_big_endian 1.0\nelement material 2\nproperty short id\n\
            element vertex 8\nproperty double x\nproperty short pad\nproperty float y\n\
            property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n\
            element face 6\nproperty list ushort short vertex_indices\nend_header\n"
            .to_vec();
        b.extend_from_slice(&[0, 1, 0, 2]);
        for (i, p) in v.iter().enumerate() {
            b.extend_from_slice(&p[0].to_be_bytes());
            b.extend_from_slice(&(-5i16).to_be_bytes());
            b.extend_from_slice(&(p[1] as f32).to_be_bytes());
            b.extend_from_slice(&(p[2] as f32).to_be_bytes());
            b.extend_from_slice(&[i as u8, 2, 3]);
        }
        for f in &q {
            b.extend_from_slice(&4u16.to_be_bytes());
            for &i in f {
                b.extend_from_slice(&(i as i16).to_be_bytes());
            }
        }
        let r = read_ply_bytes(&b, Units::Millimetres, label()).unwrap();
        check_cube(&r.mesh);
        let c = r.colors.unwrap();
        assert_eq!(c[5], [5, 2, 3]);
    }

    #[test]
    fn bad_input_names_the_item() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.ply");
        let m = cuboid(1.0, 2.0, 3.0);
        write_ply(&p, &m, Units::Millimetres, None).unwrap();
        let good = std::fs::read(&p).unwrap();
        let text = |b: &[u8]| String::from_utf8_lossy(b).into_owned();
        let with = |from: &str, to: &str| {
            let s = text(&good).replacen(from, to, 1);
            msg(read_ply_bytes(&s.into_bytes(), Units::Millimetres, label()))
        };
        let s = with("element vertex 8", "element vertex 1000");
        assert!(s.contains("header says 1000 vertex rows"), "{s}");
        let s = with("element face 12", "element face 18446744073709551615");
        assert!(s.contains("truncated"), "{s}");
        let s = with("property float y", "property flot y");
        assert!(
            s.contains("header line 6") && s.contains("unknown type 'flot'"),
            "{s}"
        );
        let s = with("property float y", "propertyy float y");
        assert!(s.contains("header line 6"), "{s}");
        let s = with("property float y", "property float w");
        assert!(s.contains("no 'y' property"), "{s}");
        let s = with("list uchar int", "list uchar float");
        assert!(
            s.contains("'vertex_indices' must be a list of an integer type"),
            "{s}"
        );
        let s = with("end_header", "end_headr");
        assert!(
            s.contains("header line 10") || s.contains("no 'end_header'"),
            "{s}"
        );
        assert!(msg(read_ply_bytes(b"plx\n", Units::Millimetres, label())).contains("not a PLY"));
        let s = with("element face", "element fase");
        assert!(s.contains("no 'face' element"), "{s}");

        // Face 3 names vertex 17: patch the second index of face 3 in the body.
        let body = good.len() - 12 * 13;
        let mut b = good.clone();
        b[body + 3 * 13 + 5..body + 3 * 13 + 9].copy_from_slice(&17i32.to_le_bytes());
        let s = msg(read_ply_bytes(&b, Units::Millimetres, label()));
        assert!(
            s.contains("face 3: names vertex 17, but the file has 8"),
            "{s}"
        );
        let mut b = good.clone();
        b[body + 5 * 13] = 2;
        let s = msg(read_ply_bytes(&b, Units::Millimetres, label()));
        assert!(s.contains("face 5"), "{s}");
        let mut b = good.clone();
        b[body - 8 * 12 + 4 * 12..body - 8 * 12 + 4 * 12 + 4]
            .copy_from_slice(&f32::INFINITY.to_le_bytes());
        let s = msg(read_ply_bytes(&b, Units::Millimetres, label()));
        assert!(s.contains("vertex 4: non-finite"), "{s}");
        let s = msg(read_ply_bytes(
            &good[..good.len() - 1],
            Units::Millimetres,
            label(),
        ));
        assert!(s.contains("face 11: truncated"), "{s}");

        let ascii = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
            property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\
            0 0 0\n1 0 0\n0 1 x\n3 0 1 2\n";
        let s = msg(read_ply_bytes(
            ascii.as_bytes(),
            Units::Millimetres,
            label(),
        ));
        assert!(s.contains("line 12, vertex 2: 'x' is not a number"), "{s}");
        let s = msg(read_ply_bytes(
            ascii
                .replace("1 x", "1 0")
                .replace("3 0 1 2", "3 0 1 300")
                .as_bytes(),
            Units::Millimetres,
            label(),
        ));
        assert!(
            s.contains("line 13, face 0: '300' is not a I32") || s.contains("names vertex 300"),
            "{s}"
        );
        let s = msg(read_ply_bytes(
            ascii
                .replace("1 x", "1 0")
                .replace("3 0 1 2", "3 0 1 1")
                .as_bytes(),
            Units::Millimetres,
            label(),
        ));
        assert!(s.contains("face 0: repeats a vertex"), "{s}");
        let s = msg(read_ply_bytes(
            ascii
                .replace("1 x", "1 0")
                .replace("3 0 1 2", "255 0 1 1")
                .as_bytes(),
            Units::Millimetres,
            label(),
        ));
        assert!(s.contains("face 0: truncated: list of 255 items"), "{s}");
    }

    #[test]
    fn writer_checks_colours() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("c.ply");
        let e = write_ply(
            &p,
            &cuboid(1.0, 1.0, 1.0),
            Units::Millimetres,
            Some(&colours(3)),
        )
        .unwrap_err();
        assert!(e.to_string().contains("3 colours given for 8 vertices"));
        assert!(!p.exists());
    }

    fn valid(format: u8) -> Vec<u8> {
        let m = cuboid(1.5, 2.0, 2.5);
        if format == 0 {
            let mut s = String::from(
                "ply\nformat ascii 1.0\nelement vertex 8\nproperty float x\nproperty float y\n\
                 property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n\
                 element face 12\nproperty list uchar int vertex_indices\nend_header\n",
            );
            for p in &m.vertices {
                writeln!(s, "{} {} {} 1 2 3", p.x, p.y, p.z).unwrap();
            }
            for f in &m.faces {
                writeln!(s, "3 {} {} {}", f[0], f[1], f[2]).unwrap();
            }
            return s.into_bytes();
        }
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("v.ply");
        if format == 1 {
            write_ply(&p, &m, Units::Millimetres, Some(&colours(8))).unwrap();
        } else {
            write_ply_f64(&p, &m, Units::Millimetres, None).unwrap();
        }
        std::fs::read(&p).unwrap()
    }

    #[test]
    fn ascii_fixture_matches_binary() {
        let a = read_ply_bytes(&valid(0), Units::Millimetres, label()).unwrap();
        let b = read_ply_bytes(&valid(2), Units::Millimetres, label()).unwrap();
        assert_eq!(a.mesh, b.mesh);
        assert_eq!(a.colors.unwrap(), vec![[1, 2, 3]; 8]);
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        #[test]
        fn truncated_never_panics(format in 0u8..3, cut in 0usize..2000) {
            let b = valid(format);
            let cut = cut.min(b.len());
            if let Ok(m) = read_ply_bytes(&b[..cut], Units::Millimetres, label()) {
                prop_assert!(m.mesh.n_faces() <= 12);
            }
        }

        #[test]
        fn mutated_never_panics(format in 0u8..3, edits in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..8)) {
            let mut b = valid(format);
            for (i, x) in edits {
                let i = i.index(b.len());
                b[i] = x;
            }
            if let Ok(m) = read_ply_bytes(&b, Units::Millimetres, label()) {
                prop_assert!(TriMesh::new(m.mesh.vertices.clone(), m.mesh.faces.clone()).is_ok());
                prop_assert!(m.colors.is_none_or(|c| c.len() == m.mesh.n_vertices()));
            }
        }
    }
}
