// The predicted velocities v* = v + Δt·a (TVCG 2017, Algorithm 1, line 8).
@group(0) @binding(1) var<uniform> clock: Control;
@group(0) @binding(2) var<storage, read> acceleration: array<vec2<f32>>;
@group(0) @binding(3) var<storage, read_write> velocity: array<vec2<f32>>;

@compute @workgroup_size(64)
fn predict(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= params.n {
        return;
    }
    velocity[i] += clock.dt * acceleration[i];
}
