//! What is in front of the sensor: a scene description (poses, filled slots, light) and
//! the world-space triangles it expands to, each with its albedo and object id. How the
//! triangles are seen is the rasterizer's business.

use camplace_config::{Cell, Table};
use nalgebra::{Isometry3, Point3, Vector3};

use serde::{Deserialize, Serialize};

use crate::scene::tray::{box_triangles, item_for, Solid, TrayModel};
use crate::Result;

/// Object id of the table and of "nothing" in the id images.
pub const ID_TABLE: u8 = 0;
/// Object id of the tray.
pub const ID_TRAY: u8 = 1;
/// Object id of the item in slot 0; the item in slot n has `ID_FIRST_ITEM + n`.
pub const ID_FIRST_ITEM: u8 = 2;
/// Object id of the occluder (the box standing for the gripper above the tray).
pub const ID_OCCLUDER: u8 = 255;

/// An axis-aligned box in the world: the occluder of a scene.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct OccluderBox {
    /// Lowest corner, world mm.
    pub min: [f64; 3],
    /// Highest corner, world mm.
    pub max: [f64; 3],
}

/// The glossy lobe of a material: normalised Blinn–Phong, whose reflectance towards a view
/// is specular (e + 8) / 8 (n.h)^e relative to a white Lambertian surface's, with h the
/// half-way vector between the light and the view and e the lobe's exponent. Where the
/// lobe is below [`Gloss::NEGLIGIBLE`] of a white Lambertian surface's it is taken as 0, so
/// the power is only taken near the mirror direction.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Gloss {
    /// Specular albedo (0: matte).
    pub specular: f64,
    /// Blinn–Phong exponent e.
    pub exponent: f64,
    /// The n.h below which the lobe is under [`Gloss::NEGLIGIBLE`].
    cos_min: f64,
}

impl Gloss {
    /// No lobe.
    pub const MATTE: Gloss = Gloss { specular: 0.0, exponent: 0.0, cos_min: 1.0 };

    /// The reflectance, relative to a white Lambertian surface's, below which the lobe is
    /// dropped: a fortieth of a grey level under full white.
    pub const NEGLIGIBLE: f64 = 1e-4;

    /// The lobe of specular albedo `specular` and roughness `roughness` (Beckmann's slope
    /// spread m), whose Blinn–Phong exponent is 2 / m² - 2 (Walter et al. 2007).
    pub fn new(specular: f64, roughness: f64) -> Gloss {
        if specular <= 0.0 {
            return Gloss::MATTE;
        }
        let exponent = (2.0 / (roughness * roughness) - 2.0).max(0.0);
        let peak = specular * (exponent + 8.0) / 8.0;
        // peak · cos^e = NEGLIGIBLE; a lobe that never reaches it (or has e = 0) is kept whole.
        let cos_min = if peak > Gloss::NEGLIGIBLE && exponent > 0.0 {
            (Gloss::NEGLIGIBLE / peak).powf(1.0 / exponent)
        } else {
            0.0
        };
        Gloss { specular, exponent, cos_min }
    }

    /// The lobe's reflectance at n.h = `cos_half` relative to a white Lambertian surface's.
    #[inline(always)]
    pub fn reflectance(&self, cos_half: f64) -> f64 {
        if self.specular <= 0.0 || cos_half <= 0.0 || cos_half < self.cos_min {
            return 0.0;
        }
        self.specular * (self.exponent + 8.0) / 8.0 * cos_half.powf(self.exponent)
    }

    /// [`Gloss::reflectance`] towards a view whose half-way vector with the light is `half`
    /// (any length) on a face of unit `normal`; the length is only taken near the mirror
    /// direction, where the lobe is not negligible.
    #[inline(always)]
    pub fn reflectance_half_way(&self, normal: &[f64; 3], half: &[f64; 3]) -> f64 {
        let dot = normal[0] * half[0] + normal[1] * half[1] + normal[2] * half[2];
        let length2 = half[0] * half[0] + half[1] * half[1] + half[2] * half[2];
        if !self.near_mirror(dot, length2) {
            return 0.0;
        }
        self.reflectance(dot / length2.sqrt())
    }

    /// Whether a half-way vector with n.h = `dot` and |h|² = `length2` lies near enough the
    /// mirror direction for the lobe not to be negligible: n.h / |h| at least cos_min, tested
    /// without the root.
    #[inline(always)]
    pub fn near_mirror(&self, dot: f64, length2: f64) -> bool {
        !(self.specular <= 0.0 || dot.is_nan() || dot <= 0.0 || dot * dot < self.cos_min * self.cos_min * length2)
    }
}

/// One scene to render: which objects are present, where, and how it is lit.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneSpec {
    /// Tray frame -> world frame.
    pub t_world_tray: Isometry3<f64>,
    /// Indices of the slots holding an item.
    pub filled: Vec<usize>,
    /// Whether the table top is present (the model builder leaves it out).
    pub table: bool,
    /// Whether the tray is present (the background capture leaves it out).
    pub tray: bool,
    /// Ambient light, in units of full white.
    pub ambient: f64,
    /// Strength of the background lamp, in units of full white on a surface facing it.
    pub lamp_strength: f64,
    /// Where the (point) lamp hangs, world mm.
    pub lamp_position: Point3<f64>,
    /// The box above the tray, if the scene has one.
    pub occluder: Option<OccluderBox>,
}

impl SceneSpec {
    /// The same scene without the tray, its items and the occluder, as the background
    /// capture sees it.
    pub fn background(&self) -> SceneSpec {
        SceneSpec { tray: false, filled: Vec::new(), occluder: None, ..self.clone() }
    }
}

/// One world-space triangle of a scene.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SceneTriangle {
    /// Corners, world mm.
    pub vertices: [Point3<f64>; 3],
    /// Unit normal by the winding (the renderer turns it towards whoever looks).
    pub normal: Vector3<f64>,
    /// Lambertian albedo.
    pub albedo: f64,
    /// Glossy lobe.
    pub gloss: Gloss,
    /// Object id: table, tray, item or occluder (see `ID_*`).
    pub id: u8,
}

/// The objects a cell places on its table, in their own frames, ready to be posed.
#[derive(Debug, Clone, PartialEq)]
pub struct Objects {
    /// The table top.
    pub table: Table,
    /// The tray and its slots.
    pub tray: TrayModel,
    /// Albedo of the tray.
    pub tray_albedo: f64,
    /// One item, in the item frame.
    pub item: Solid,
    /// Albedo of the items.
    pub item_albedo: f64,
    /// Glossy lobes of the table, the tray and the items (matte with specular off).
    pub gloss: [Gloss; 3],
    /// Albedo of the occluder.
    pub occluder_albedo: f64,
    /// Slots that, when filled, hold this solid (slot frame) instead of the item: an item
    /// standing askew, a foreign object. Empty in every study; tests set it.
    pub odd_items: Vec<(usize, Solid)>,
}

impl Objects {
    /// The table, tray and item of a cell (mesh files are read here).
    pub fn from_cell(cell: &Cell) -> Result<Objects> {
        Ok(Objects {
            table: cell.table.clone(),
            tray: TrayModel::from_cell(cell)?,
            tray_albedo: cell.tray.albedo,
            item: item_for(cell)?,
            item_albedo: cell.items.albedo,
            gloss: if cell.effects.specular {
                [
                    Gloss::new(cell.table.specular, cell.table.roughness),
                    Gloss::new(cell.tray.specular, cell.tray.roughness),
                    Gloss::new(cell.items.specular, cell.items.roughness),
                ]
            } else {
                [Gloss::MATTE; 3]
            },
            occluder_albedo: cell.occluder.albedo,
            odd_items: Vec::new(),
        })
    }

    /// Writes the world triangles of `spec` into `out` (cleared first), table first, then
    /// the tray, then the items by slot. Slots past the tray's last, or whose id would not
    /// fit a byte, hold no item; triangles of zero area are left out.
    pub fn triangles(&self, spec: &SceneSpec, out: &mut Vec<SceneTriangle>) {
        out.clear();
        if spec.table {
            let [sx, sy] = self.table.size;
            let (hx, hy) = (sx / 2.0, sy / 2.0);
            let c = [
                Point3::new(-hx, -hy, 0.0),
                Point3::new(hx, -hy, 0.0),
                Point3::new(hx, hy, 0.0),
                Point3::new(-hx, hy, 0.0),
            ];
            let table = (self.table.albedo, self.gloss[0], ID_TABLE);
            push(out, [c[0], c[1], c[2]], table);
            push(out, [c[0], c[2], c[3]], table);
        }
        if let Some(b) = &spec.occluder {
            for t in box_triangles(b.min, b.max) {
                push(out, t, (self.occluder_albedo, Gloss::MATTE, ID_OCCLUDER));
            }
        }
        if !spec.tray {
            return;
        }
        for t in &self.tray.solid.triangles {
            push(out, t.map(|p| spec.t_world_tray * p), (self.tray_albedo, self.gloss[1], ID_TRAY));
        }
        for &n in &spec.filled {
            let Some(slot) = self.tray.slot_pose(n) else { continue };
            let Some(id) = u8::try_from(n).ok().and_then(|n| n.checked_add(ID_FIRST_ITEM)) else { continue };
            let pose = spec.t_world_tray * slot;
            let solid = self.odd_items.iter().find(|(m, _)| *m == n).map_or(&self.item, |(_, s)| s);
            for t in &solid.triangles {
                push(out, t.map(|p| pose * p), (self.item_albedo, self.gloss[2], id));
            }
        }
    }
}

/// Pushes a triangle of (albedo, gloss, id).
fn push(out: &mut Vec<SceneTriangle>, vertices: [Point3<f64>; 3], (albedo, gloss, id): (f64, Gloss, u8)) {
    let n = (vertices[1] - vertices[0]).cross(&(vertices[2] - vertices[0]));
    let len = n.norm();
    if len > 1e-12 && len.is_finite() {
        out.push(SceneTriangle { vertices, normal: n / len, albedo, gloss, id });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};

    #[test]
    fn ids_and_poses() {
        let cell = Cell::default();
        let objects = Objects::from_cell(&cell).unwrap();
        let t = Isometry3::from_parts(
            Translation3::new(12.0, -7.0, 0.0),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.4),
        );
        let spec = SceneSpec {
            t_world_tray: t,
            filled: vec![1, 5, 99],
            table: true,
            tray: true,
            ambient: 0.2,
            lamp_strength: 0.3,
            lamp_position: Point3::new(0.0, 0.0, 1000.0),
            occluder: None,
        };
        let mut tris = Vec::new();
        objects.triangles(&spec, &mut tris);
        let count = |id: u8| tris.iter().filter(|t| t.id == id).count();
        assert_eq!(count(ID_TABLE), 2);
        assert_eq!(count(ID_TRAY), objects.tray.solid.triangles.len());
        assert_eq!(count(ID_FIRST_ITEM + 1), 12);
        assert_eq!(count(ID_FIRST_ITEM + 5), 12);
        assert_eq!(tris.len(), 2 + objects.tray.solid.triangles.len() + 24);
        // Item 5's top centre is above its slot centre, moved by the tray pose.
        let slot = objects.tray.slots[5];
        let want = t * Point3::new(slot[0], slot[1], slot[2] + cell.items.size[2]);
        let top: Vec<_> = tris.iter().filter(|t| t.id == ID_FIRST_ITEM + 5 && t.normal.z > 0.99).collect();
        assert_eq!(top.len(), 2);
        let centre = top.iter().flat_map(|t| t.vertices).fold(Vector3::zeros(), |a, p| a + p.coords) / 6.0;
        // The two top triangles share a diagonal, so their six corners average to the centre.
        assert!((centre - want.coords).norm() < 1e-9);
        objects.triangles(&spec.background(), &mut tris);
        assert_eq!(tris.len(), 2);
    }

    #[test]
    fn the_lobe_is_the_blinn_phong_one_down_to_the_negligible_level() {
        for (specular, roughness) in [(0.05, 0.1), (0.3, 0.5), (1.0, 0.02), (0.001, 0.9)] {
            let g = Gloss::new(specular, roughness);
            let full = |c: f64| specular * (g.exponent + 8.0) / 8.0 * c.powf(g.exponent);
            for i in 0..=2000 {
                let c = i as f64 / 2000.0;
                let (got, want) = (g.reflectance(c), full(c));
                if want >= Gloss::NEGLIGIBLE * (1.0 + 1e-9) {
                    assert_eq!(got, want, "specular {specular}, roughness {roughness}, n.h {c}");
                } else {
                    assert!(got == 0.0 || got == want, "specular {specular}, roughness {roughness}, n.h {c}: {got}");
                }
            }
        }
        assert_eq!(Gloss::new(0.0, 0.1).reflectance(1.0), 0.0);
        // The same lobe from an unnormalised half-way vector.
        let g = Gloss::new(0.05, 0.1);
        let n = [0.0, 0.6, 0.8];
        for i in 0..=500 {
            let a = i as f64 * std::f64::consts::PI / 500.0;
            let h = [3.0 * a.sin(), 0.0, 3.0 * a.cos()];
            let want = g.reflectance((n[0] * h[0] + n[1] * h[1] + n[2] * h[2]) / 3.0);
            let got = g.reflectance_half_way(&n, &h);
            assert!(
                (got - want).abs() <= 1e-12 * want.max(1.0) || (got == 0.0 && want < Gloss::NEGLIGIBLE * 1.01),
                "angle {a}: {got} vs {want}"
            );
        }
    }
}
