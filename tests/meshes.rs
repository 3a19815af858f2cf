//! Meshes the tests write: unions of axis-aligned boxes as binary STL.

/// Boxes `(min, max)` in mm as one binary STL (12 triangles a box, outward faces).
pub fn boxes_stl(boxes: &[([f32; 3], [f32; 3])]) -> Vec<u8> {
    let mut triangles: Vec<[[f32; 3]; 3]> = Vec::new();
    for &(lo, hi) in boxes {
        let p = |i: usize, j: usize, k: usize| [[lo[0], hi[0]][i], [lo[1], hi[1]][j], [lo[2], hi[2]][k]];
        let faces = [
            [p(0, 0, 0), p(0, 0, 1), p(0, 1, 1), p(0, 1, 0)],
            [p(1, 0, 0), p(1, 1, 0), p(1, 1, 1), p(1, 0, 1)],
            [p(0, 0, 0), p(1, 0, 0), p(1, 0, 1), p(0, 0, 1)],
            [p(0, 1, 0), p(0, 1, 1), p(1, 1, 1), p(1, 1, 0)],
            [p(0, 0, 0), p(0, 1, 0), p(1, 1, 0), p(1, 0, 0)],
            [p(0, 0, 1), p(1, 0, 1), p(1, 1, 1), p(0, 1, 1)],
        ];
        for [a, b, c, d] in faces {
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    let mut out = vec![0u8; 80];
    out.extend((triangles.len() as u32).to_le_bytes());
    for t in triangles {
        out.extend([0u8; 12]);
        for v in t.iter().flatten() {
            out.extend(v.to_le_bytes());
        }
        out.extend([0u8; 2]);
    }
    out
}

/// A closed box of `size` mm from the origin as a binary STL.
pub fn box_stl(size: [f32; 3]) -> Vec<u8> {
    boxes_stl(&[([0.0; 3], size)])
}

/// An open tray `[x, y]` mm with a floor and walls `wall` thick and `height` high, its
/// origin at the bottom face's centre, and a tab on the +x wall that breaks its symmetry.
pub fn tray_stl(x: f32, y: f32, floor: f32, wall: f32, height: f32) -> Vec<u8> {
    let (hx, hy) = (x / 2.0, y / 2.0);
    boxes_stl(&[
        ([-hx, -hy, 0.0], [hx, hy, floor]),
        ([-hx, -hy, 0.0], [-hx + wall, hy, height]),
        ([hx - wall, -hy, 0.0], [hx, hy, height]),
        ([-hx, -hy, 0.0], [hx, -hy + wall, height]),
        ([-hx, hy - wall, 0.0], [hx, hy, height]),
        ([hx, -15.0, 0.0], [hx + 20.0, 15.0, height * 0.6]),
    ])
}
