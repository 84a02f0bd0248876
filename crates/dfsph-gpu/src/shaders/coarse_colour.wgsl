// `W_k 1` for the colour k = `slot.parity`: 1 on the particles of aggregates of that colour
// (`CoarseSpace::colour_indicator`), as a search direction whose products give `A W_k 1`.
@group(0) @binding(1) var<uniform> slot: Slot;
@group(0) @binding(2) var<storage, read> coarse: Coarse;
@group(0) @binding(3) var<storage, read> aggregate: array<u32>;
@group(0) @binding(4) var<storage, read_write> direction: array<f32>;

@compute @workgroup_size(64)
fn coarse_colour(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= params.n {
        return;
    }
    let a = aggregate[i];
    var w = 0.0;
    if a != COARSE_NONE && coarse_colour_of(coarse_cell(a)) == slot.parity {
        w = 1.0;
    }
    direction[i] = w;
}
