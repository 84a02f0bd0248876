// The coarse space's restrictions, one invocation per aggregate c, summed over particles
// in the fine grid's order: with `slot.mode` 0, Wᵀ(a e): Σ a_i e_i over the aggregate's
// particles (`CoarseSpace::restrict`, the deflated start); with mode 1, (A W)ᵀ z: Σ (A W)_{i,c}
// z_i over the particles whose colour-k entry goes to c, k the colour of c (they lie within
// half a cell around it), with z_i = a_i (factor_i/Δt) e_i (`CoarseSpace::restrict_aw`).
@group(0) @binding(1) var<uniform> slot: Slot;
@group(0) @binding(2) var<uniform> clock: Control;
@group(0) @binding(3) var<storage, read> coarse: Coarse;
@group(0) @binding(4) var<storage, read> fluid: array<vec2<f32>>;
@group(0) @binding(5) var<storage, read> fluid_sorted: array<u32>;
@group(0) @binding(6) var<storage, read> fluid_starts: array<u32>;
@group(0) @binding(7) var<storage, read> densities: array<vec4<f32>>;
@group(0) @binding(8) var<storage, read> aggregate: array<u32>;
@group(0) @binding(9) var<storage, read> aw: array<vec4<f32>>;
@group(0) @binding(10) var<storage, read> carries: array<f32>;
@group(0) @binding(11) var<storage, read> residual: array<f32>;
@group(0) @binding(12) var<storage, read_write> y: array<f32>;

@compute @workgroup_size(64)
fn coarse_restrict(@builtin(global_invocation_id) id: vec3<u32>) {
    let c = id.x;
    if c >= coarse.count {
        return;
    }
    let home = coarse_cell(c);
    let colour = coarse_colour_of(home);
    let aw_mode = slot.mode == 1u;
    var lo = coarse.origin + vec2<f32>(home) * coarse.cell;
    var hi = lo + vec2<f32>(coarse.cell);
    if aw_mode {
        lo -= vec2<f32>(0.5 * coarse.cell);
        hi += vec2<f32>(0.5 * coarse.cell);
    }
    let r = fine_cells(lo, hi);
    var sum = 0.0;
    for (var row = r.z; row <= r.w; row++) {
        let first = fluid_starts[row * params.nx + r.x];
        let last = fluid_starts[row * params.nx + r.y + 1u];
        for (var s = first; s < last; s++) {
            let i = fluid_sorted[s];
            if aggregate[i] == COARSE_NONE {
                continue;
            }
            if aw_mode {
                let v = aw[i][colour];
                if v != 0.0 && coarse_target(coarse_place(fluid[i]), colour) == c {
                    sum += v * (carries[i] * densities[i].y / clock.dt * residual[i]);
                }
            } else if aggregate[i] == c {
                sum += carries[i] * residual[i];
            }
        }
    }
    y[c] = sum;
}
