//! Every decoder of outside bytes against damaged input: all truncations, seeded random
//! byte flips and headers that promise more than the file holds. A decoder may accept a
//! damaged file that still reads (a flipped digit is a different number), but it must
//! return, never panic, abort or loop, and a header that lies about sizes is an error.

use std::path::Path;

use super::{mesh, pfm, ply};
use crate::test_draw::Draw;
use crate::{Cell, RigFile, TruthFile};

/// Seeded test damage, the same on every run.
struct Damage(Draw);

impl Damage {
    /// `good` with one to four bytes replaced by random ones.
    fn flip(&mut self, good: &[u8]) -> Vec<u8> {
        let mut b = good.to_vec();
        for _ in 0..1 + self.0.below(4) {
            let i = self.0.below(b.len());
            b[i] = self.0.next() as u8;
        }
        b
    }
}

/// Runs `decode` on every prefix of `good` (at most `max_cuts` evenly spread) and on
/// `flips` damaged copies; returns how many of the truncations were accepted.
fn torture(good: &[u8], max_cuts: usize, flips: usize, seed: u64, decode: impl Fn(&[u8]) -> bool) -> usize {
    assert!(decode(good), "the undamaged sample must decode");
    let step = good.len().div_ceil(max_cuts).max(1);
    let accepted = (0..good.len()).step_by(step).filter(|&n| decode(&good[..n])).count();
    let mut d = Damage(Draw::new(seed));
    for _ in 0..flips {
        decode(&d.flip(good));
    }
    accepted
}

fn sample_cloud() -> Vec<u8> {
    let points: Vec<[f32; 3]> = (0..200).map(|i| [i as f32, (i * 7 % 13) as f32, -(i as f32) * 0.5]).collect();
    let normals: Vec<[f32; 3]> = (0..200).map(|_| [0.0, 0.0, 1.0]).collect();
    ply::encode_cloud(&points, Some(&normals))
}

#[test]
fn ply_survives_truncation_and_flips() {
    let good = sample_cloud();
    let accepted = torture(&good, 4000, 4000, 1, |b| ply::decode_ply(b).is_ok());
    assert_eq!(accepted, 0, "a cut binary PLY is short of its vertices");
    let ascii = b"ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2\n3 0 2 3\n";
    torture(ascii, 4000, 4000, 2, |b| ply::decode_ply(b).is_ok());
}

#[test]
fn ply_headers_that_promise_too_much_are_refused() {
    let huge = [
        "element vertex 18446744073709551615\nproperty float x\nproperty float y\nproperty float z\n",
        "element vertex 1000000000000\nproperty float x\nproperty float y\nproperty float z\n",
        "element vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement junk 18446744073709551615\n",
        "element vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 4294967295\nproperty list uint uint vertex_indices\n",
    ];
    for (i, elements) in huge.iter().enumerate() {
        for format in ["binary_little_endian", "ascii"] {
            let text = format!("ply\nformat {format} 1.0\n{elements}end_header\n0 0 0 1 1 1 2 2 2\n");
            let e = ply::decode_ply(text.as_bytes()).expect_err(&format!("case {i} {format}"));
            assert!(!e.key().is_empty(), "case {i}: {e}");
        }
    }
    // A list that claims four billion entries ends at the end of the file.
    let mut b = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uint uint vertex_indices\nend_header\n".to_vec();
    b.extend(std::iter::repeat_n(0u8, 36));
    b.extend(u32::MAX.to_le_bytes());
    b.extend([0u8; 12]);
    assert!(ply::decode_ply(&b).is_err());
}

#[test]
fn pfm_survives_truncation_and_flips() {
    let data: Vec<f32> = (0..24 * 16).map(|i| i as f32 * 0.25).collect();
    let good = pfm::encode_pfm(24, 16, &data);
    let accepted = torture(&good, 4000, 4000, 3, |b| pfm::decode_pfm(b).is_ok());
    assert_eq!(accepted, 0, "a cut PFM is short of its floats");
    for head in
        ["Pf\n4294967296 4294967296\n-1\n", "Pf\n18446744073709551615 2\n-1\n", "PF\n0 5\n-1\n", "Pf\n2 2\nnan\n"]
    {
        let mut b = head.as_bytes().to_vec();
        b.extend([0u8; 64]);
        assert!(pfm::decode_pfm(&b).is_err(), "{head:?}");
    }
}

#[test]
fn meshes_survive_truncation_and_flips() {
    let mut stl = vec![0u8; 80];
    stl.extend(3u32.to_le_bytes());
    for t in 0..3 {
        stl.extend([0u8; 12]);
        for v in 0..9 {
            stl.extend(((t * 9 + v) as f32).to_le_bytes());
        }
        stl.extend([0u8; 2]);
    }
    torture(&stl, 4000, 4000, 4, |b| mesh::decode_stl(b).is_ok());
    let ascii = b"solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid\n";
    torture(ascii, 4000, 4000, 5, |b| mesh::decode_stl(b).is_ok());
    let obj = b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\nf -1 -2 -3\n";
    torture(obj, 4000, 4000, 6, |b| mesh::decode_obj(b).is_ok());
    assert!(mesh::decode_obj(b"v 0 0 0\nf -9223372036854775808 1 1\n").is_err());
}

#[test]
fn rig_and_truth_json_survive_truncation_and_flips() {
    let cam = crate::CameraFile {
        width: 640,
        height: 480,
        k: [[812.0, 0.0, 319.5], [0.0, 812.0, 239.5], [0.0, 0.0, 1.0]],
        dist: [0.0; 5],
        t_world_camera: [[1.0, 0.0, 0.0, -40.0], [0.0, -1.0, 0.0, 0.0], [0.0, 0.0, -1.0, 600.0], [0.0, 0.0, 0.0, 1.0]],
    };
    let mut right = cam.clone();
    right.t_world_camera[0][3] = 80.0;
    let rig = RigFile { left: cam.clone(), right, projector: Some(cam), rectified: None }.to_json();
    let accepted =
        torture(rig.as_bytes(), 4000, 4000, 7, |b| std::str::from_utf8(b).is_ok_and(|t| RigFile::from_json(t).is_ok()));
    assert_eq!(accepted, 0, "a cut rig.json is not JSON");
    let truth = r#"{"T_world_tray": [[1,0,0,5],[0,1,0,-3],[0,0,1,0],[0,0,0,1]], "filled": [0, 3],
        "lighting": {"ambient": 0.3, "lamp_strength": 0.5, "lamp_position": [1, 2, 900]}, "seed": 1, "scenario": 2}"#;
    let accepted = torture(truth.as_bytes(), 4000, 4000, 8, |b| {
        std::str::from_utf8(b).is_ok_and(|t| TruthFile::from_json(t).is_ok())
    });
    assert_eq!(accepted, 0, "a cut truth.json is not JSON");
}

#[test]
fn cell_toml_survives_truncation_and_flips() {
    let text = crate::cell::DEFAULT_CELL_TOML;
    torture(text.as_bytes(), 3000, 3000, 9, |b| {
        std::str::from_utf8(b).is_ok_and(|t| Cell::from_toml_str(t, Path::new(".")).is_ok())
    });
}

#[test]
fn placement_strings_survive_truncation_and_flips_and_read_back() {
    let base = Cell::default().placement;
    let good = b"r=605,alpha=32,baseline=81,vergence=3.5,azimuth=10";
    torture(good, good.len(), 20_000, 7, |b| {
        let Ok(text) = std::str::from_utf8(b) else { return false };
        match base.with_overrides(text) {
            Ok(p) => {
                // What it accepts, it writes back as text that reads the same.
                assert_eq!(base.with_overrides(&p.to_string()).ok(), Some(p), "{text:?}");
                true
            }
            Err(_) => false,
        }
    });
}

#[test]
fn images_survive_truncation_and_flips_within_the_pixel_budget() {
    use image::ImageEncoder;
    let pixels: Vec<u8> = (0..48u32 * 32).map(|v| (v * 7) as u8).collect();
    let mut good = Vec::new();
    image::codecs::png::PngEncoder::new(&mut good).write_image(&pixels, 48, 32, image::ExtendedColorType::L8).unwrap();
    torture(&good, good.len(), 5_000, 8, |b| match super::png::decode_gray(b) {
        Ok(g) => {
            assert!((g.width * g.height) as u64 <= crate::MAX_IMAGE_PIXELS && g.data.len() == g.width * g.height);
            true
        }
        Err(_) => false,
    });
}
