// Each point's index into its cell's slot, by its arrival rank.
@group(0) @binding(1) var<storage, read> keys: array<u32>;
@group(0) @binding(2) var<storage, read> rank: array<u32>;
@group(0) @binding(3) var<storage, read> starts: array<u32>;
@group(0) @binding(4) var<storage, read_write> sorted: array<u32>;

@compute @workgroup_size(64)
fn grid_scatter(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= grid.n {
        return;
    }
    sorted[starts[keys[i]] + rank[i]] = i;
}
