// The walls' forces on every fluid particle besides their pressure, added to the
// accelerations: their friction (`dfsph::viscosity::WallFriction`), the Laplacian viscosity
// against the wall particles, 8ν_b Σ_b Ψ_b ∇W_ib (v_ib·x_ib)/(|x_ib|² + 0.01h²), and the
// hydrostatic part of the mirrored walls' ghost pressure (`dfsph::forces`, `GhostPressure`),
// −Σ_b Ψ_b (g_s·(x_b − x_i)) ∇W_ib with g_s = `consts.ghost_slope`.
@group(0) @binding(1) var<uniform> consts: StepConsts;
@group(0) @binding(2) var<storage, read> fluid: array<vec2<f32>>;
@group(0) @binding(3) var<storage, read> velocity: array<vec2<f32>>;
@group(0) @binding(4) var<storage, read> walls: array<vec2<f32>>;
// (Ψ_b, v_b, 0) per wall particle.
@group(0) @binding(5) var<storage, read> wall_data: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read> wall_sorted: array<u32>;
@group(0) @binding(7) var<storage, read> wall_starts: array<u32>;
@group(0) @binding(8) var<storage, read_write> acceleration: array<vec2<f32>>;

@compute @workgroup_size(64)
fn wall_forces(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= params.n {
        return;
    }
    let x = fluid[i];
    let v = velocity[i];
    let home = cell_of(x);
    let h2 = params.h * params.h;
    var laplace = vec2<f32>(0.0);
    var ghosts = vec2<f32>(0.0);
    for (var k = 0u; k < 9u; k++) {
        let wall_range = wall_slots(home, k);
        for (var s = wall_range.x; s < wall_range.y; s++) {
            let b = wall_sorted[s];
            let d = x - walls[b];
            let r2 = dot(d, d);
            if r2 < h2 {
                let data = wall_data[b];
                let vib = v - data.yz;
                let g = data.x * grad_w(d, sqrt(r2));
                laplace += g * (dot(vib, d) / (r2 + consts.eps2));
                ghosts += g * dot(consts.ghost_slope, -d);
            }
        }
    }
    acceleration[i] += consts.friction * laplace - ghosts;
}
