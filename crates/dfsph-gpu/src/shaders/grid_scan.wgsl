// Exclusive prefix sum of the cells' counts into `starts` (cells + 1 entries), by one
// workgroup: each invocation sums a contiguous chunk, the 256 chunk sums are scanned in
// shared memory, then each chunk is written out in order.
@group(0) @binding(1) var<storage, read> counts: array<u32>;
@group(0) @binding(2) var<storage, read_write> starts: array<u32>;

const THREADS: u32 = 256u;
var<workgroup> sums: array<u32, 256>;

@compute @workgroup_size(256)
fn grid_scan(@builtin(local_invocation_id) lid: vec3<u32>) {
    let t = lid.x;
    let chunk = (grid.cells + THREADS - 1u) / THREADS;
    let first = min(t * chunk, grid.cells);
    let last = min(first + chunk, grid.cells);
    var total = 0u;
    for (var c = first; c < last; c++) {
        total += counts[c];
    }
    sums[t] = total;
    workgroupBarrier();
    // Hillis–Steele inclusive scan of the chunk sums.
    for (var step = 1u; step < THREADS; step *= 2u) {
        var add = 0u;
        if t >= step {
            add = sums[t - step];
        }
        workgroupBarrier();
        sums[t] += add;
        workgroupBarrier();
    }
    var running = sums[t] - total;
    for (var c = first; c < last; c++) {
        starts[c] = running;
        running += counts[c];
    }
    if t == THREADS - 1u {
        starts[grid.cells] = sums[t];
    }
}
