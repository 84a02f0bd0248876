// Each fluid particle's aggregate: the number of the coarse cell it lies in where it
// carries pressure, COARSE_NONE elsewhere (`CoarseSpace::aggregate`).
@group(0) @binding(1) var<storage, read> coarse: Coarse;
@group(0) @binding(2) var<storage, read> fluid: array<vec2<f32>>;
@group(0) @binding(3) var<storage, read> carries: array<f32>;
@group(0) @binding(4) var<storage, read_write> aggregate: array<u32>;

@compute @workgroup_size(64)
fn coarse_assign(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= params.n {
        return;
    }
    var a = COARSE_NONE;
    if carries[i] > 0.0 {
        a = coarse_key(coarse_place(fluid[i]).cell);
    }
    aggregate[i] = a;
}
