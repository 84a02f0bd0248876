// `A W_k 1` for the colour k = `slot.parity`, per fluid particle: −Δt·a_i·q_i with q the
// rate change of the colour's velocity change (`cg_push`), stored as component k of the
// particle's `aw` (`CoarseSpace::set_colour_product`).
@group(0) @binding(1) var<uniform> slot: Slot;
@group(0) @binding(2) var<uniform> clock: Control;
@group(0) @binding(3) var<storage, read> fluid: array<vec2<f32>>;
@group(0) @binding(4) var<storage, read> fluid_sorted: array<u32>;
@group(0) @binding(5) var<storage, read> fluid_starts: array<u32>;
@group(0) @binding(6) var<storage, read> densities: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read> velocity: array<vec2<f32>>;
@group(0) @binding(8) var<storage, read> carries: array<f32>;
@group(0) @binding(9) var<storage, read_write> aw: array<vec4<f32>>;

@compute @workgroup_size(64)
fn coarse_product(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= params.n {
        return;
    }
    let q = dot(velocity[i], densities[i].zw) - params.volume * velocity_sum(i, fluid[i]);
    var row = aw[i];
    row[slot.parity] = -clock.dt * q * carries[i];
    aw[i] = row;
}
