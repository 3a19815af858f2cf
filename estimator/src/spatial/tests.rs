//! One seeded oracle for every index: random clouds, and each query checked against a plain
//! scan of all points.

use nalgebra::Point3;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::{voxel_key, NearestGrid, Neighbours, SceneGrid, VoxelTable};

fn random_cloud(rng: &mut ChaCha8Rng, n: usize, half: [f32; 3]) -> Vec<Point3<f32>> {
    (0..n)
        .map(|_| {
            Point3::new(
                rng.random_range(-half[0]..half[0]),
                rng.random_range(-half[1]..half[1]),
                rng.random_range(-half[2]..half[2]),
            )
        })
        .collect()
}

fn random_query(rng: &mut ChaCha8Rng, half: [f32; 3]) -> Point3<f32> {
    random_cloud(rng, 1, half.map(|h| h * 1.2))[0]
}

/// Squared distances from `q` to every point, in cloud order.
fn scan(cloud: &[Point3<f32>], q: &Point3<f32>) -> Vec<f32> {
    cloud.iter().map(|p| (p - q).norm_squared()).collect()
}

#[test]
fn every_index_answers_as_a_brute_force_scan() {
    let mut rng = ChaCha8Rng::seed_from_u64(2024);
    let mut neighbours = Neighbours::new();
    let mut scene = SceneGrid::new(6.0, 16);
    let mut table = VoxelTable::default();
    let (mut within, mut nearest) = (Vec::new(), Vec::new());
    for &(n, half) in &[(20, [30.0, 30.0, 5.0]), (700, [60.0, 40.0, 10.0]), (4000, [80.0, 80.0, 20.0])] {
        let cloud = random_cloud(&mut rng, n, half);

        // Neighbours: radius and k-nearest queries.
        let cell = rng.random_range(1.0..8.0);
        neighbours.build(&cloud, cell).unwrap();
        for _ in 0..200 {
            let q = random_query(&mut rng, half);
            let d2 = scan(&cloud, &q);
            let radius = rng.random_range(0.5..25.0f32);
            neighbours.within(&q, radius, &mut within);
            within.sort_unstable();
            let want: Vec<u32> = (0..n as u32).filter(|&i| d2[i as usize] <= radius * radius).collect();
            assert_eq!(within, want, "within {radius} of {q}");
            let k = rng.random_range(1..20);
            neighbours.nearest(&q, k, radius, &mut nearest);
            let mut want: Vec<(u32, f32)> =
                (0..n as u32).map(|i| (i, d2[i as usize])).filter(|&(_, e)| e <= radius * radius).collect();
            want.sort_by(|a, b| (a.1, a.0).partial_cmp(&(b.1, b.0)).unwrap());
            want.truncate(k);
            assert_eq!(nearest, want, "{k} nearest within {radius} of {q}");
        }

        // SceneGrid: any point within half a cell, and the nearest one.
        scene.rebuild(&cloud);
        let reach2 = 9.0;
        for _ in 0..500 {
            let q = random_query(&mut rng, half);
            let best = scan(&cloud, &q).into_iter().fold(f32::INFINITY, f32::min);
            assert_eq!(scene.any_within(&q, reach2), best <= reach2);
            let got = scene.nearest_within(&q, reach2).map(|p| (p - q).norm_squared());
            assert_eq!(got, (best <= reach2).then_some(best));
        }

        // NearestGrid: a point within a cell diagonal of the nearest, and none only when no
        // point lies within the reach it was built for.
        let (resolution, max_distance) = (2.0f32, 6.0f32);
        let grid = NearestGrid::new(&cloud, resolution, max_distance);
        for _ in 0..500 {
            let q = random_query(&mut rng, half);
            let exact = scan(&cloud, &q).into_iter().fold(f32::INFINITY, f32::min).sqrt();
            match grid.lookup(&q) {
                Some(i) => assert!((cloud[i as usize] - q).norm() <= exact + resolution * 3f32.sqrt() + 1e-4),
                None => assert!(exact > max_distance, "missed a point {exact} mm away"),
            }
        }

        // VoxelTable: slots numbered by each voxel's first point, as a scan of earlier
        // points finds them.
        let size = rng.random_range(1.0..10.0f32);
        let inv = 1.0 / size;
        table.reset(n);
        let voxel = |p: &Point3<f32>| [p.x, p.y, p.z].map(|c| (c * inv).floor() as i64);
        let mut firsts: Vec<usize> = Vec::new();
        for (i, p) in cloud.iter().enumerate() {
            let (slot, new) = table.slot(voxel_key(p, inv).unwrap());
            let seen = firsts.iter().position(|&f| voxel(&cloud[f]) == voxel(p));
            assert_eq!(new, seen.is_none());
            assert_eq!(slot as usize, seen.unwrap_or(firsts.len()));
            if seen.is_none() {
                firsts.push(i);
            }
        }
    }
}

#[test]
fn floor_i32_equals_the_cast_of_the_floor() {
    use super::floor_i32;
    let special = [
        0.0,
        -0.0,
        0.5,
        -0.5,
        1.0,
        -1.0,
        -1e-30,
        2147483520.0,
        -2147483648.0,
        -2147483904.0,
        3e9,
        -3e9,
        16777217.0,
        -16777217.0,
        f32::MAX,
        f32::MIN,
        f32::INFINITY,
        f32::NEG_INFINITY,
        f32::NAN,
    ];
    for v in special {
        assert_eq!(floor_i32(v), v.floor() as i32, "{v}");
    }
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    for _ in 0..200_000 {
        let scale = 10f32.powi(rng.random_range(-3..10));
        let v = rng.random_range(-1.0f32..1.0) * scale;
        assert_eq!(floor_i32(v), v.floor() as i32, "{v}");
        let bits = f32::from_bits(rng.random::<u32>());
        assert_eq!(floor_i32(bits), bits.floor() as i32, "{bits}");
    }
}
