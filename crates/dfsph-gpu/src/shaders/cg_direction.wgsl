// After a conjugate-gradient iteration, per fluid particle: the next search direction
// p = z + β p with z_i = a_i (factor_i/Δt) e_i (p = z for β = 0), made A-orthogonal to the
// coarse space when deflating, p −= W E⁻¹ (A W)ᵀ z (`coarse_restrict` and `coarse_solve`
// left E⁻¹ (A W)ᵀ z in `y`); or, where `cg_control.wgsl` found that the step made the error
// grow, the step taken back (κ −= α p, v −= α Δv).
@group(0) @binding(1) var<uniform> clock: Control;
@group(0) @binding(2) var<storage, read> state: CgState;
@group(0) @binding(3) var<storage, read> densities: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> residual: array<f32>;
@group(0) @binding(5) var<storage, read> carries: array<f32>;
@group(0) @binding(6) var<storage, read> change: array<vec2<f32>>;
@group(0) @binding(7) var<storage, read_write> total: array<f32>;
@group(0) @binding(8) var<storage, read_write> velocity: array<vec2<f32>>;
@group(0) @binding(9) var<storage, read_write> direction: array<f32>;
@group(0) @binding(10) var<uniform> solve: CgSolve;
@group(0) @binding(11) var<storage, read> aggregate: array<u32>;
@group(0) @binding(12) var<storage, read> y: array<f32>;

@compute @workgroup_size(64)
fn cg_direction(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= params.n {
        return;
    }
    if state.take_back == 1u {
        total[i] -= state.alpha * direction[i];
        velocity[i] -= state.alpha * change[i];
        return;
    }
    var p = carries[i] * densities[i].y / clock.dt * residual[i];
    if state.beta != 0.0 {
        p += state.beta * direction[i];
    }
    if solve.coarse_cell > 0.0 && aggregate[i] != 0xffffffffu {
        p -= y[aggregate[i]];
    }
    direction[i] = p;
}
