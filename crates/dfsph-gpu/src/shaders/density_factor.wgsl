// Per fluid particle, the SPH density relative to rest, Σ_j V W(x_i − x_j) over the fluid
// (the particle itself included) plus Σ_b Ψ_b W(x_i − x_b) over the walls, and the DFSPH
// factor 1 / (|g_i|² + Σ_j |V ∇W_ij|²) with g_i = Σ_j V ∇W_ij + w Σ_b Ψ_b ∇W_ib (TVCG 2017,
// eq. 13 in volumes; w the walls' gradient weight), at most `max_factor`, 0 where the sums
// are below `eps`: `dfsph::solver::density_and_factor`. The 2D cubic spline of support h
// (`dfsph::kernel::Kernel`). Both sets are sorted into the same
// cells (`grid_*.wgsl`), whose side is h: the 3 × 3 cells around a particle hold every
// neighbour, visited row by row and, in a cell, by index.
@group(0) @binding(1) var<storage, read> fluid: array<vec2<f32>>;
@group(0) @binding(2) var<storage, read> fluid_sorted: array<u32>;
@group(0) @binding(3) var<storage, read> fluid_starts: array<u32>;
@group(0) @binding(4) var<storage, read> walls: array<vec2<f32>>;
// (Ψ_b, v_b, 0) per wall particle.
@group(0) @binding(5) var<storage, read> wall_data: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read> wall_sorted: array<u32>;
@group(0) @binding(7) var<storage, read> wall_starts: array<u32>;
// (ρ/ρ0, factor, g_i).
@group(0) @binding(8) var<storage, read_write> out: array<vec4<f32>>;

@compute @workgroup_size(64)
fn density_factor(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= params.n {
        return;
    }
    let x = fluid[i];
    let home = cell_of(x);
    let h2 = params.h * params.h;
    var fluid_sum = 0.0;
    var wall_sum = 0.0;
    var fluid_grad = vec2<f32>(0.0);
    var wall_grad = vec2<f32>(0.0);
    var grad_sq = 0.0;
    for (var k = 0u; k < 9u; k++) {
        let fluid_range = fluid_slots(home, k);
        for (var s = fluid_range.x; s < fluid_range.y; s++) {
            let d = x - fluid[fluid_sorted[s]];
            let r2 = dot(d, d);
            if r2 < h2 {
                let r = sqrt(r2);
                fluid_sum += w(r);
                let g = params.volume * grad_w(d, r);
                fluid_grad += g;
                grad_sq += dot(g, g);
            }
        }
        let wall_range = wall_slots(home, k);
        for (var s = wall_range.x; s < wall_range.y; s++) {
            let b = wall_sorted[s];
            let d = x - walls[b];
            let r2 = dot(d, d);
            if r2 < h2 {
                let r = sqrt(r2);
                let volume = wall_data[b].x;
                wall_sum += volume * w(r);
                wall_grad += volume * grad_w(d, r);
            }
        }
    }
    let g = fluid_grad + params.wall_weight * wall_grad;
    let denom = dot(g, g) + grad_sq;
    var factor = 0.0;
    if denom > params.eps {
        factor = min(1.0 / denom, params.max_factor);
    }
    out[i] = vec4<f32>(params.volume * fluid_sum + wall_sum, factor, g);
}
