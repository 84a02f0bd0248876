// Each point's cell key, and its arrival rank in its cell (atomic: in no fixed order).
@group(0) @binding(1) var<storage, read> pos: array<vec2<f32>>;
@group(0) @binding(2) var<storage, read_write> keys: array<u32>;
@group(0) @binding(3) var<storage, read_write> counts: array<atomic<u32>>;
@group(0) @binding(4) var<storage, read_write> rank: array<u32>;

@compute @workgroup_size(64)
fn grid_keys(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= grid.n {
        return;
    }
    let c = floor((pos[i] - grid.origin) * grid.inv_cell);
    let cx = u32(clamp(c.x, 0.0, f32(grid.nx - 1u)));
    let cy = u32(clamp(c.y, 0.0, f32(grid.ny - 1u)));
    let key = cy * grid.nx + cx;
    keys[i] = key;
    rank[i] = atomicAdd(&counts[key], 1u);
}
