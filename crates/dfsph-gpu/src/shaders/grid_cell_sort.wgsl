// Each cell's points in increasing index: the order of a stable counting sort, whatever
// order the atomics gave them (cells hold a handful of points: insertion sort).
@group(0) @binding(1) var<storage, read> starts: array<u32>;
@group(0) @binding(2) var<storage, read_write> sorted: array<u32>;

@compute @workgroup_size(64)
fn grid_cell_sort(@builtin(global_invocation_id) id: vec3<u32>) {
    let c = id.x;
    if c >= grid.cells {
        return;
    }
    let first = starts[c];
    let last = starts[c + 1u];
    for (var k = first + 1u; k < last; k++) {
        let v = sorted[k];
        var j = k;
        while j > first && sorted[j - 1u] > v {
            sorted[j] = sorted[j - 1u];
            j -= 1u;
        }
        sorted[j] = v;
    }
}
