//! PLY point clouds and meshes: `binary_little_endian` written, ascii and binary read.
//! Points are float x y z in mm, with optional nx ny nz; faces are vertex index lists.

use std::path::Path;

use crate::{Error, ErrorKind};

/// A PLY point cloud's contents: points, optionally with normals, mm.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PlyCloud {
    pub points: Vec<[f32; 3]>,
    pub normals: Option<Vec<[f32; 3]>>,
}

/// Vertices and triangles read from a PLY.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PlyData {
    pub vertices: Vec<[f32; 3]>,
    pub normals: Option<Vec<[f32; 3]>>,
    pub faces: Vec<[u32; 3]>,
}

/// Encodes a binary little-endian PLY of points (and normals when given).
pub fn encode_cloud(points: &[[f32; 3]], normals: Option<&[[f32; 3]]>) -> Vec<u8> {
    let mut head = format!(
        "ply\nformat binary_little_endian 1.0\ncomment camplace, mm\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\n",
        points.len()
    );
    if normals.is_some() {
        head.push_str("property float nx\nproperty float ny\nproperty float nz\n");
    }
    head.push_str("end_header\n");
    let mut out = head.into_bytes();
    for (i, p) in points.iter().enumerate() {
        for v in p {
            out.extend_from_slice(&v.to_le_bytes());
        }
        if let Some(n) = normals {
            for v in &n[i] {
                out.extend_from_slice(&v.to_le_bytes());
            }
        }
    }
    out
}

/// Writes a point cloud.
pub fn write_cloud(path: &Path, points: &[[f32; 3]], normals: Option<&[[f32; 3]]>) -> Result<(), Error> {
    if let Some(n) = normals {
        assert_eq!(n.len(), points.len(), "one normal per point");
    }
    super::write_atomic(path, &encode_cloud(points, normals))
}

/// Reads a point cloud (faces, if any, are ignored).
pub fn read_cloud(path: &Path) -> Result<PlyCloud, Error> {
    let d = read_ply(path)?;
    Ok(PlyCloud { points: d.vertices, normals: d.normals })
}

/// Every `k`-th of `points`, `k` the smallest whole step that leaves at most `most` of them
/// (all of them when they are that few): how a cloud is thinned for a file or a page.
pub fn thinned<T>(points: &[T], most: usize) -> impl Iterator<Item = &T> {
    points.iter().step_by(points.len().div_ceil(most.max(1)).max(1))
}

/// Reads a PLY file.
pub fn read_ply(path: &Path) -> Result<PlyData, Error> {
    let bytes = super::read::read_bounded(path, super::read::FileKind::Data)?;
    decode_ply(&bytes).map_err(|e| e.in_file(path))
}

#[derive(Clone, Copy, PartialEq)]
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
    fn parse(s: &str) -> Option<Scalar> {
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
    fn read(self, b: &[u8], little: bool) -> f64 {
        macro_rules! num {
            ($t:ty, $n:expr) => {{
                let mut a = [0u8; $n];
                a.copy_from_slice(&b[..$n]);
                (if little { <$t>::from_le_bytes(a) } else { <$t>::from_be_bytes(a) }) as f64
            }};
        }
        match self {
            Scalar::I8 => b[0] as i8 as f64,
            Scalar::U8 => b[0] as f64,
            Scalar::I16 => num!(i16, 2),
            Scalar::U16 => num!(u16, 2),
            Scalar::I32 => num!(i32, 4),
            Scalar::U32 => num!(u32, 4),
            Scalar::F32 => num!(f32, 4),
            Scalar::F64 => num!(f64, 8),
        }
    }
}

enum Property {
    Scalar(String, Scalar),
    List(String, Scalar, Scalar),
}

struct Element {
    name: String,
    count: usize,
    props: Vec<Property>,
}

#[derive(PartialEq)]
enum Encoding {
    Ascii,
    Little,
    Big,
}

/// Decodes PLY bytes.
pub fn decode_ply(bytes: &[u8]) -> Result<PlyData, Error> {
    let bad = |field: &str, m: String| Error::new(ErrorKind::Format, field, m);
    if !bytes.starts_with(b"ply") {
        return Err(bad("header", "not a PLY file: expected it to start with \"ply\"".into()));
    }
    let end = find(bytes, b"end_header").ok_or_else(|| bad("header", "no end_header line".into()))?;
    let mut body_start = end + b"end_header".len();
    if bytes.get(body_start) == Some(&b'\r') {
        body_start += 1;
    }
    body_start += 1;
    let head = String::from_utf8_lossy(&bytes[..end]);
    let mut enc = None;
    let mut elements: Vec<Element> = Vec::new();
    for line in head.lines().skip(1) {
        let t: Vec<&str> = line.split_whitespace().collect();
        match t.as_slice() {
            ["format", f, _] => {
                enc = Some(match *f {
                    "ascii" => Encoding::Ascii,
                    "binary_little_endian" => Encoding::Little,
                    "binary_big_endian" => Encoding::Big,
                    _ => return Err(bad("format", format!("unknown PLY format \"{f}\""))),
                })
            }
            ["element", name, count] => elements.push(Element {
                name: name.to_string(),
                count: count.parse().map_err(|_| bad("element", format!("bad count \"{count}\"")))?,
                props: Vec::new(),
            }),
            ["property", "list", c, i, name] => {
                let el = elements.last_mut().ok_or_else(|| bad("property", "property before element".into()))?;
                let c = Scalar::parse(c).ok_or_else(|| bad("property", format!("unknown type \"{c}\"")))?;
                let i = Scalar::parse(i).ok_or_else(|| bad("property", format!("unknown type \"{i}\"")))?;
                el.props.push(Property::List(name.to_string(), c, i));
            }
            ["property", ty, name] => {
                let el = elements.last_mut().ok_or_else(|| bad("property", "property before element".into()))?;
                let s = Scalar::parse(ty).ok_or_else(|| bad("property", format!("unknown type \"{ty}\"")))?;
                el.props.push(Property::Scalar(name.to_string(), s));
            }
            _ => {}
        }
    }
    let enc = enc.ok_or_else(|| bad("format", "no format line".into()))?;
    let body = bytes.get(body_start..).unwrap_or(&[]);
    let mut out = PlyData::default();
    let mut reader = Reader { body, pos: 0, enc, ascii: None };
    if reader.enc == Encoding::Ascii {
        reader.ascii = Some(String::from_utf8_lossy(body).split_whitespace().map(str::to_string).collect::<Vec<_>>());
    }
    // Every count in the header is bounded by what the body can hold before anything is
    // allocated or looped over: a record takes at least one byte per scalar (one token in
    // ascii), so a header that promises more than the file has is refused at once.
    let available = match &reader.ascii {
        Some(tokens) => tokens.len() as u128,
        None => body.len() as u128,
    };
    let mut needed: u128 = 0;
    for el in &elements {
        let min_record: u128 = el
            .props
            .iter()
            .map(|p| {
                let s = match p {
                    Property::Scalar(_, s) | Property::List(_, s, _) => *s,
                };
                if reader.ascii.is_some() {
                    1
                } else {
                    s.size() as u128
                }
            })
            .sum();
        if el.count > 0 && min_record == 0 {
            return Err(bad(&el.name, format!("element declares {} records but no properties", el.count)));
        }
        needed += el.count as u128 * min_record;
        if needed > available {
            let unit = if reader.ascii.is_some() { "numbers" } else { "bytes" };
            return Err(bad(
                &el.name,
                format!(
                    "the header declares {} {} records, more than the file holds (at least {needed} {unit} needed, {available} present)",
                    el.count, el.name
                ),
            ));
        }
    }
    for el in &elements {
        let idx = |n: &str| el.props.iter().position(|p| matches!(p, Property::Scalar(name, _) if name == n));
        let (ix, iy, iz) = (idx("x"), idx("y"), idx("z"));
        let (inx, iny, inz) = (idx("nx"), idx("ny"), idx("nz"));
        let has_normals = inx.is_some() && iny.is_some() && inz.is_some();
        if el.name == "vertex" {
            if ix.is_none() || iy.is_none() || iz.is_none() {
                return Err(bad("vertex", "expected float properties x, y and z".into()));
            }
            out.vertices.reserve(el.count);
            if has_normals {
                out.normals = Some(Vec::with_capacity(el.count));
            }
        }
        let mut vals = vec![0f64; el.props.len()];
        for _ in 0..el.count {
            let mut face: Vec<u32> = Vec::new();
            for (k, p) in el.props.iter().enumerate() {
                match p {
                    Property::Scalar(_, s) => vals[k] = reader.next(*s).map_err(|m| bad(&el.name, m))?,
                    Property::List(name, c, i) => {
                        let n = reader.next(*c).map_err(|m| bad(&el.name, m))?;
                        if !(n >= 0.0 && n.fract() == 0.0) {
                            return Err(bad(&el.name, format!("expected a list length of 0 or more, got {n}")));
                        }
                        let keep = el.name == "face" && (name == "vertex_indices" || name == "vertex_index");
                        // The reader stops at the end of the file, so a huge length ends there.
                        for _ in 0..n as u64 {
                            let v = reader.next(*i).map_err(|m| bad(&el.name, m))?;
                            if keep {
                                if !(v >= 0.0 && v.fract() == 0.0 && v <= u32::MAX as f64) {
                                    return Err(bad(&el.name, format!("expected a vertex index, got {v}")));
                                }
                                face.push(v as u32);
                            }
                        }
                    }
                }
            }
            if el.name == "vertex" {
                out.vertices.push([vals[ix.unwrap()] as f32, vals[iy.unwrap()] as f32, vals[iz.unwrap()] as f32]);
                if let Some(n) = out.normals.as_mut() {
                    n.push([vals[inx.unwrap()] as f32, vals[iny.unwrap()] as f32, vals[inz.unwrap()] as f32]);
                }
            } else if el.name == "face" {
                for j in 1..face.len().saturating_sub(1) {
                    out.faces.push([face[0], face[j], face[j + 1]]);
                }
            }
        }
    }
    let nv = out.vertices.len() as u32;
    if out.faces.iter().flatten().any(|&i| i >= nv) {
        return Err(bad("face", format!("a face names a vertex beyond the {nv} vertices")));
    }
    Ok(out)
}

struct Reader<'a> {
    body: &'a [u8],
    pos: usize,
    enc: Encoding,
    ascii: Option<Vec<String>>,
}

impl Reader<'_> {
    /// The next value, or what is wrong: the end of the file, or a token that is no number.
    fn next(&mut self, s: Scalar) -> Result<f64, String> {
        if let Some(tokens) = &self.ascii {
            let t = tokens.get(self.pos).ok_or("file ends early")?;
            self.pos += 1;
            return t.parse().map_err(|_| format!("expected a number, got \"{t}\""));
        }
        let b = self.body.get(self.pos..self.pos + s.size()).ok_or("file ends early")?;
        self.pos += s.size();
        Ok(s.read(b, self.enc == Encoding::Little))
    }
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thinning_keeps_every_kth_point_and_at_most_the_most() {
        for len in [0usize, 1, 5, 99, 100, 101, 1000, 12_345] {
            for most in [0usize, 1, 7, 100, 20_000] {
                let points: Vec<usize> = (0..len).collect();
                let got: Vec<usize> = thinned(&points, most).copied().collect();
                // Slow and obvious: the smallest step k whose every-k-th points are few enough.
                let k = (1..=len.max(1)).find(|k| len.div_ceil(*k) <= most.max(1)).unwrap_or(1);
                let want: Vec<usize> = (0..len).filter(|i| i % k == 0).collect();
                assert_eq!(got, want, "len {len}, most {most}");
            }
        }
    }

    #[test]
    fn binary_round_trip_with_normals() {
        let p = vec![[1.0, 2.0, 3.0], [-4.0, 5.5, 0.0]];
        let n = vec![[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]];
        let d = decode_ply(&encode_cloud(&p, Some(&n))).unwrap();
        assert_eq!(d.vertices, p);
        assert_eq!(d.normals.unwrap(), n);
    }

    #[test]
    fn ascii_mesh_with_quads() {
        let text = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n";
        let d = decode_ply(text.as_bytes()).unwrap();
        assert_eq!(d.vertices.len(), 4);
        assert_eq!(d.faces, vec![[0, 1, 2], [0, 2, 3]]);
    }

    #[test]
    fn not_a_ply() {
        assert_eq!(decode_ply(b"solid x").unwrap_err().key(), "header");
    }
}
