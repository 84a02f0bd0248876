// The coarse matrix's rows before symmetrising, one invocation per aggregate a
// (`CoarseSpace::factorise`): T(a, o) = Σ_{i in a} (A W)_{i, a+o} for the 3 × 3 cells a + o
// around it, summed over the aggregate's particles in the fine grid's order. A particle's
// entry for colour k goes to the colour-k cell within reach of it (`coarse_target`).
@group(0) @binding(1) var<storage, read> coarse: Coarse;
@group(0) @binding(2) var<storage, read> fluid: array<vec2<f32>>;
@group(0) @binding(3) var<storage, read> fluid_sorted: array<u32>;
@group(0) @binding(4) var<storage, read> fluid_starts: array<u32>;
@group(0) @binding(5) var<storage, read> aggregate: array<u32>;
@group(0) @binding(6) var<storage, read> aw: array<vec4<f32>>;
// Nine per aggregate, row by row from the lower left.
@group(0) @binding(7) var<storage, read_write> rows: array<f32>;

@compute @workgroup_size(64)
fn coarse_rows(@builtin(global_invocation_id) id: vec3<u32>) {
    let a = id.x;
    if a >= coarse.count {
        return;
    }
    var t = array<f32, 9>(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    let home = coarse_cell(a);
    let lo = coarse.origin + vec2<f32>(home) * coarse.cell;
    let r = fine_cells(lo, lo + vec2<f32>(coarse.cell));
    for (var y = r.z; y <= r.w; y++) {
        let first = fluid_starts[y * params.nx + r.x];
        let last = fluid_starts[y * params.nx + r.y + 1u];
        for (var s = first; s < last; s++) {
            let i = fluid_sorted[s];
            if aggregate[i] != a {
                continue;
            }
            let place = coarse_place(fluid[i]);
            let v = aw[i];
            for (var k = 0u; k < 4u; k++) {
                let target_key = coarse_target(place, k);
                if v[k] == 0.0 || target_key == COARSE_NONE {
                    continue;
                }
                let o = vec2<i32>(coarse_cell(target_key)) - vec2<i32>(home) + vec2<i32>(1);
                t[u32(o.y * 3 + o.x)] += v[k];
            }
        }
    }
    for (var k = 0u; k < 9u; k++) {
        rows[a * 9u + k] = t[k];
    }
}
