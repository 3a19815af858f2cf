//! The tray model's outline in the left image: the model's surface points placed at the pose,
//! projected through the left camera (with its distortion), and the convex hull of what lands
//! in the image, the polygon the status page draws over the frame.

use camplace_config::thinned;
use camplace_estimator::{geometry::Camera, Model};
use nalgebra::{Isometry3, Point3};

/// Most model points projected for one outline.
const OUTLINE_POINTS: usize = 4000;

/// The model's points (tray frame, mm), thinned to [`OUTLINE_POINTS`].
pub(crate) fn outline_points(model: &Model) -> Vec<Point3<f64>> {
    let all: Vec<Point3<f64>> = model
        .views
        .iter()
        .flat_map(|v| v.points.iter())
        .chain(model.feature_points.iter())
        .map(|p| p.cast::<f64>())
        .collect();
    thinned(&all, OUTLINE_POINTS).copied().collect()
}

/// The outline of `points` at `t_world_tray` in `camera`'s image: a convex polygon, pixels.
pub(crate) fn outline(points: &[Point3<f64>], t_world_tray: &Isometry3<f64>, camera: &Camera) -> Vec<[f32; 2]> {
    let (w, h) = (camera.width as f64, camera.height as f64);
    let mut pixels: Vec<[f64; 2]> = points
        .iter()
        .filter_map(|p| camera.project(&(t_world_tray * p)))
        .filter(|q| q.x >= 0.0 && q.y >= 0.0 && q.x < w && q.y < h)
        .map(|q| [q.x, q.y])
        .collect();
    convex_hull(&mut pixels).into_iter().map(|[x, y]| [x as f32, y as f32]).collect()
}

/// Andrew's monotone chain: the hull counter-clockwise (in x-right, y-up terms), no
/// repeated first point.
fn convex_hull(points: &mut [[f64; 2]]) -> Vec<[f64; 2]> {
    points.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    if points.len() < 3 {
        return points.to_vec();
    }
    let cross = |o: [f64; 2], a: [f64; 2], b: [f64; 2]| (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]);
    let mut hull: Vec<[f64; 2]> = Vec::with_capacity(2 * points.len());
    for pass in 0..2 {
        let start = hull.len();
        let ordered: Box<dyn Iterator<Item = &[f64; 2]>> =
            if pass == 0 { Box::new(points.iter()) } else { Box::new(points.iter().rev()) };
        for &p in ordered {
            while hull.len() >= start + 2 && cross(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0 {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
    }
    hull
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_hull_of_a_square_with_inner_points_is_its_corners() {
        let mut pts = vec![[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0], [1.0, 1.0], [0.5, 1.5], [1.0, 0.0]];
        let hull = convex_hull(&mut pts);
        assert_eq!(hull.len(), 4, "{hull:?}");
        for corner in [[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]] {
            assert!(hull.contains(&corner), "{hull:?}");
        }
        // Every point lies inside or on the hull: the slow check, by the sign of each edge.
        for p in &pts {
            for k in 0..hull.len() {
                let (a, b) = (hull[k], hull[(k + 1) % hull.len()]);
                assert!((b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]) >= -1e-12);
            }
        }
    }
}
