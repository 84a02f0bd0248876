// The conjugate-gradient density solve's start, per fluid particle (`density_solve` of
// `dfsph::pressure::conjugate_gradient`): the warm start κ_i = max(p_i/ρ0, 0)·Δt/c where
// the particle is inside the water (the stored pressure is the physical one, c·κ/Δt, with c
// the lattice's gradient consistency), zero elsewhere and without a warm start.
@group(0) @binding(1) var<uniform> solve: CgSolve;
@group(0) @binding(2) var<uniform> clock: Control;
@group(0) @binding(3) var<storage, read> densities: array<vec4<f32>>;
// (wall flux, neighbour count).
@group(0) @binding(4) var<storage, read> flux: array<vec2<f32>>;
// p/ρ0 of the previous step.
@group(0) @binding(5) var<storage, read> stored: array<f32>;
// The running total κ.
@group(0) @binding(6) var<storage, read_write> total: array<f32>;

@compute @workgroup_size(64)
fn cg_begin(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= params.n {
        return;
    }
    var kappa = 0.0;
    if solve.warm == 1u && cg_inside(densities[i].x, flux[i].y) {
        kappa = max(stored[i], 0.0) * clock.dt / solve.consistency;
    }
    total[i] = kappa;
}
