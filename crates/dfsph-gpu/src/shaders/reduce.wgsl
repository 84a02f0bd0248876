// One level of a reduction over `n` values: each workgroup folds 256 consecutive values
// (the products a_i·b_i for a dot product) in a fixed tree, so the result is the same bits
// on every run. `op`: 0 sum, 1 maximum, 2 dot product (first level only; later levels sum).
struct Reduce {
    n: u32,
    op: u32,
    pad0: u32,
    pad1: u32,
}

@group(0) @binding(0) var<uniform> reduce: Reduce;
@group(0) @binding(1) var<storage, read> a: array<f32>;
@group(0) @binding(2) var<storage, read> b: array<f32>;
@group(0) @binding(3) var<storage, read_write> partial: array<f32>;

var<workgroup> values: array<f32, 256>;

@compute @workgroup_size(256)
fn reduce_level(
    @builtin(local_invocation_id) lid: vec3<u32>,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let t = lid.x;
    let group = wid.x + wid.y * groups.x;
    let i = group * 256u + t;
    var v = 0.0;
    if reduce.op == 1u {
        v = -3.4028235e38;
    }
    if i < reduce.n {
        v = a[i];
        if reduce.op == 2u {
            v *= b[i];
        }
    }
    values[t] = v;
    workgroupBarrier();
    for (var half = 128u; half > 0u; half /= 2u) {
        if t < half {
            if reduce.op == 1u {
                values[t] = max(values[t], values[t + half]);
            } else {
                values[t] += values[t + half];
            }
        }
        workgroupBarrier();
    }
    if t == 0u {
        partial[group] = values[0];
    }
}
