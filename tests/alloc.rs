//! The estimator's allocation policy, proven: after a few warm-up frames, `process` makes
//! no heap allocation on any thread it runs on, for both capture methods. Its own test
//! binary, for its counting global allocator.
//!
//! The frame loop runs on a rayon worker, as a deployment's does, and every stage runs on
//! rayon's pool, so the counter counts allocations on the pool's threads. Other threads of
//! the process are not the estimator's: the test harness's main thread, for one, formats a
//! "has been running for over 60 seconds" notice on a loaded machine.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Mutex;

use camplace_config::Cell;
use camplace_estimator::{Estimator, EstimatorConfig, PoseEstimate};
use camplace_sim::{background_scene, build_model, draw_scenario, noise_key, Frame, Method, Simulator};
use nalgebra::Point3;

/// Counts allocations (and growths) while `COUNTING` is set, on rayon's worker threads.
struct Counting;

static COUNTING: AtomicBool = AtomicBool::new(false);
static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

// SAFETY: every method hands its arguments unchanged to the system allocator, which keeps
// GlobalAlloc's contract, and returns its result; the counting beside it touches only
// atomics and never allocates, so it cannot re-enter the allocator.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        // SAFETY: the caller's `layout` meets `GlobalAlloc::alloc`'s terms, which are
        // `System.alloc`'s.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` came from this allocator, that is from `System`, with `layout`.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        // SAFETY: `ptr` came from `System` with `layout`, and the caller's `new_size` meets
        // `GlobalAlloc::realloc`'s terms, which are `System.realloc`'s.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

/// Counts one allocation when counting is on and this thread is one of rayon's workers
/// (a thread-local pointer read: it never allocates).
fn count() {
    if COUNTING.load(Ordering::Relaxed) && rayon::current_thread_index().is_some() {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// The counter sees every thread, so the tests of this binary take turns.
static SERIAL: Mutex<()> = Mutex::new(());

/// Counts the heap allocations `f` makes on any thread.
fn allocations(f: impl FnOnce()) -> usize {
    ALLOCATIONS.store(0, Ordering::SeqCst);
    COUNTING.store(true, Ordering::SeqCst);
    f();
    COUNTING.store(false, Ordering::SeqCst);
    ALLOCATIONS.load(Ordering::SeqCst)
}

/// An estimator on a few rendered frames at the paper's optimum, warmed up on them.
fn warmed_up(method: Method) -> (Estimator, Vec<Frame>) {
    let mut cell = Cell::default();
    // Fewer matches keep the test quick; the buffers are the same.
    cell.estimator.k = 10;
    let placement = cell.placement.with_overrides("r=605,alpha=32,baseline=81,vergence=3.5").unwrap();
    let seed = 3;
    let model = build_model(&cell, &placement, method, seed).unwrap();
    let mut sim = Simulator::new(&cell, &placement, seed).unwrap();
    let mut background = Frame::default();
    sim.render(&background_scene(&cell, seed), method, noise_key(seed, 0, true), &mut background);
    let frames: Vec<Frame> = (0..4)
        .map(|i| {
            let mut frame = Frame::default();
            let scene = draw_scenario(&cell, seed, i).scene();
            sim.render(&scene, method, noise_key(seed, i, false), &mut frame);
            frame
        })
        .collect();
    let mut estimator = Estimator::new(&EstimatorConfig::from(&cell), sim.rig(), model, method).unwrap();
    estimator.set_background(&background.shots.left, &background.shots.right).unwrap();
    for frame in &frames {
        estimator.process(&frame.shots.left, &frame.shots.right).unwrap();
    }
    (estimator, frames)
}

#[test]
fn cloud_to_pose_allocates_nothing_in_steady_state() {
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let (mut estimator, frames) = warmed_up(Method::OneShot);
    let clouds: Vec<Vec<Point3<f32>>> = frames
        .iter()
        .map(|f| {
            estimator.process(&f.shots.left, &f.shots.right).unwrap();
            estimator.reconstruction().cloud.points.clone()
        })
        .collect();
    for cloud in &clouds {
        estimator.process_cloud(cloud).unwrap();
    }
    // The frame loop runs on a rayon worker, as a deployment's does: parallel stages called
    // from outside the pool go through rayon's injector queue, which allocates a block every
    // 63 calls.
    let counts: Vec<(usize, bool)> = rayon::scope(|_| {
        (0..20)
            .map(|i| {
                let cloud = &clouds[i % clouds.len()];
                let mut result = Ok(PoseEstimate::default());
                let n = allocations(|| result = estimator.process_cloud(cloud));
                let pose = result.unwrap();
                (n, pose.found)
            })
            .collect()
    });
    let found = counts.iter().filter(|c| c.1).count();
    let allocating: Vec<(usize, usize)> =
        counts.iter().enumerate().filter(|(_, c)| c.0 > 0).map(|(i, c)| (i, c.0)).collect();
    assert!(allocating.is_empty(), "(frame, allocations) in process_cloud: {allocating:?}");
    // The frames must exercise every stage, RANSAC's success path and ICP included, and the
    // slot judge after them.
    assert!(found > 0, "no frame found the tray, so ICP never ran");
    let last_found = counts.last().is_some_and(|c| c.1);
    assert_eq!(estimator.slots().len(), if last_found { 8 } else { 0 }, "the model's slots, judged under a pose");
}

/// Runs 20 frames on a rayon worker and asserts that none allocates; returns how many found
/// the tray.
fn assert_frames_allocate_nothing(estimator: &mut Estimator, frames: &[Frame]) -> usize {
    rayon::scope(|_| {
        (0..20)
            .filter(|&i| {
                let frame = &frames[i % frames.len()];
                let mut result = Ok(PoseEstimate::default());
                let n = allocations(|| result = estimator.process(&frame.shots.left, &frame.shots.right));
                assert_eq!(n, 0, "frame {i}: {n} allocations in process");
                result.unwrap().found
            })
            .count()
    })
}

/// The whole one-shot frame, rectification and stereo matching included: no allocation at
/// all once warmed up.
#[test]
fn stereo_frame_to_pose_allocates_nothing_in_steady_state() {
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let (mut estimator, frames) = warmed_up(Method::OneShot);
    let found = assert_frames_allocate_nothing(&mut estimator, &frames);
    assert!(found > 0, "no frame found the tray, so ICP never ran");
}

/// The whole 12-shot frame, twelve rectified pairs and phase decoding included: no
/// allocation at all once warmed up.
#[test]
fn phase_frame_to_pose_allocates_nothing_in_steady_state() {
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let (mut estimator, frames) = warmed_up(Method::Phase12);
    let found = assert_frames_allocate_nothing(&mut estimator, &frames);
    assert!(found > 0, "no frame found the tray, so ICP never ran");
}
