// The warm start as the first increments, per fluid particle: the warm-start stiffness
// everywhere, or, gated, only where the residual pass just found the particle compressed
// (`Sweeps::warm_start` of the CPU solver: a droplet stopped by a wall in the last step
// would otherwise be thrown back).
@group(0) @binding(1) var<uniform> solve: Solve;
@group(0) @binding(2) var<storage, read> jac: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> increment: array<f32>;

@compute @workgroup_size(64)
fn jacobi_warm(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= params.n {
        return;
    }
    let state = jac[i];
    var warm = state.y;
    if solve.gated == 1u && !(state.w > 0.0) {
        warm = 0.0;
    }
    increment[i] = warm;
}
