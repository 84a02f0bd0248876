// The velocity change of a stiffness field κ, per fluid particle (`dfsph::solver::
// apply_pressure`, TVCG 2017 eq. 9 and 12 in volumes): −κ_i g_i − V Σ_j κ_j ∇W_ij. Two
// entry points: `cg_warm` adds it to the velocities (the warm start), `cg_push` writes it
// (a search direction's velocity change).
@group(0) @binding(1) var<storage, read> fluid: array<vec2<f32>>;
@group(0) @binding(2) var<storage, read> fluid_sorted: array<u32>;
@group(0) @binding(3) var<storage, read> fluid_starts: array<u32>;
@group(0) @binding(4) var<storage, read> densities: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read> kappa: array<f32>;
@group(0) @binding(6) var<storage, read_write> out: array<vec2<f32>>;

fn push(i: u32) -> vec2<f32> {
    return -kappa[i] * densities[i].zw - params.volume * kappa_sum(i, fluid[i]);
}

@compute @workgroup_size(64)
fn cg_warm(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i < params.n {
        out[i] += push(i);
    }
}

@compute @workgroup_size(64)
fn cg_push(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i < params.n {
        out[i] = push(i);
    }
}
