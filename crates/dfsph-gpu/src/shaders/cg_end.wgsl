// The conjugate-gradient solve's end, per fluid particle: the physical pressure
// p/ρ0 = c·κ/Δt (c the lattice's gradient consistency), which the next step's warm start
// and the outputs read.
@group(0) @binding(1) var<uniform> solve: CgSolve;
@group(0) @binding(2) var<uniform> clock: Control;
@group(0) @binding(3) var<storage, read> total: array<f32>;
@group(0) @binding(4) var<storage, read_write> stored: array<f32>;

@compute @workgroup_size(64)
fn cg_end(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i < params.n {
        stored[i] = total[i] * solve.consistency / clock.dt;
    }
}
