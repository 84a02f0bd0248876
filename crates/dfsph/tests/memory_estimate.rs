//! `Scene::memory_estimate` against what a simulation really allocates (issue 32): a global
//! allocator that counts bytes in use records the peak while a scene is built, stepped and
//! snapshotted. The estimate must be an upper bound, and not more than twice the peak, on
//! scenes that stress each of its terms: plain water (per-particle arrays and pairs), the
//! conjugate-gradient solve (its scratch), a wall-heavy flat tank (boundary particles and
//! wall pairs), a small block in a large tank (grid cells) and obstacles.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use dfsph::scene::{FluidBlock, Obstacle, Tank};
use dfsph::{Scene, Simulation};

struct Counting;

static IN_USE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            let now = IN_USE.fetch_add(layout.size(), Ordering::Relaxed) + layout.size();
            PEAK.fetch_max(now, Ordering::Relaxed);
        }
        p
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) };
        IN_USE.fetch_sub(layout.size(), Ordering::Relaxed);
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            if new_size >= layout.size() {
                let grow = new_size - layout.size();
                let now = IN_USE.fetch_add(grow, Ordering::Relaxed) + grow;
                PEAK.fetch_max(now, Ordering::Relaxed);
            } else {
                IN_USE.fetch_sub(layout.size() - new_size, Ordering::Relaxed);
            }
        }
        p
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// Peak bytes allocated, above what was in use before, while `scene` is built, stepped
/// `steps` times and snapshotted.
fn measured_peak(scene: &Scene, steps: usize) -> usize {
    let before = IN_USE.load(Ordering::Relaxed);
    PEAK.store(before, Ordering::Relaxed);
    {
        let mut sim = Simulation::new(scene).unwrap();
        for _ in 0..steps {
            let st = *sim.step();
            assert_eq!(st.clamped + st.non_finite, 0, "{}: {st:?}", scene.name);
        }
        let snapshot = sim.snapshot();
        assert_eq!(snapshot.id.len(), sim.fluid_count());
    }
    PEAK.load(Ordering::Relaxed) - before
}

fn block(min: [f64; 2], max: [f64; 2]) -> FluidBlock {
    FluidBlock {
        min,
        max,
        velocity: [0.0, 0.0],
    }
}

/// A tank [0, tank] with one block of fluid [0, fluid] in its corner.
fn tank_with_block(name: &str, tank: [f64; 2], fluid: [f64; 2]) -> Scene {
    Scene {
        name: name.into(),
        tank: Tank {
            min: [0.0, 0.0],
            max: tank,
        },
        fluid: vec![block([0.0, 0.0], fluid)],
        ..Scene::default()
    }
}

/// One test, so no other test's allocations run beside the measurements.
#[test]
fn the_estimate_is_an_upper_bound_within_twice_the_peak() {
    // Warm rayon's pool up first: its threads' own allocations are not the scene's.
    let mut warm = dfsph::scene::builtin("dam-break").unwrap();
    warm.particle_radius = 0.05;
    measured_peak(&warm, 2);

    let mut scenes = Vec::new();
    let mut s = dfsph::scene::builtin("dam-break").unwrap();
    // Through the collapse and the wave's impact on the far wall (t ≈ 0.6 s).
    scenes.push((s.clone(), 700));
    s.particle_radius = 0.005;
    s.name = "dam-break r = 5 mm".into();
    scenes.push((s, 20));
    let mut s = dfsph::scene::builtin("hydrostatic").unwrap();
    s.particle_radius = 0.0075;
    scenes.push((s, 20));
    scenes.push((dfsph::scene::builtin("obstacle").unwrap(), 40));
    scenes.push((tank_with_block("flat", [60.0, 0.5], [60.0, 0.06]), 20));
    scenes.push((
        tank_with_block("small block in a large tank", [40.0, 30.0], [0.5, 0.5]),
        20,
    ));
    scenes.push((
        Scene {
            name: "obstacles".into(),
            obstacles: (0..20)
                .map(|k| Obstacle::Rect {
                    min: [1.2 + 0.12 * k as f64, 0.0],
                    max: [1.25 + 0.12 * k as f64, 0.1 + 0.05 * k as f64],
                })
                .chain([Obstacle::Polyline {
                    points: vec![[0.0, 2.5], [4.0, 2.6], [2.0, 2.9]],
                }])
                .collect(),
            ..Scene::default()
        },
        30,
    ));

    let mut report = String::new();
    for (scene, steps) in &scenes {
        scene.validate().unwrap();
        let estimate = scene.memory_estimate().simulation();
        let peak = measured_peak(scene, *steps) as u64;
        let ratio = estimate as f64 / peak as f64;
        report += &format!(
            "{}: {} fluid, {} boundary (estimated), peak {} B ({:.0} B per fluid particle), \
             estimate {} B, ratio {ratio:.2}\n",
            scene.name,
            scene.fluid_particle_count(),
            scene.boundary_particle_estimate(),
            peak,
            peak as f64 / scene.fluid_particle_count() as f64,
            estimate
        );
        assert!(
            (1.0..=2.0).contains(&ratio),
            "{}: estimate {estimate} B against a peak of {peak} B\n{report}",
            scene.name
        );
    }
    println!("{report}");
}
