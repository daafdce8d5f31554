//! The per-Gaussian and per-pair kernels convert no float to an unsigned
//! integer. AVX2 has no such instruction, so lavapipe converts each lane on
//! its own, with a compare and a branch a lane; in the preprocess and keys
//! kernels that cost about a tenth of their time (docs/bench/splat.md,
//! "Tile counts without unsigned conversions"). Whole numbers convert with
//! `whole_to_uint` (common.glsl); `uint(int(x))` does not help, since
//! spirv-opt folds it back into `OpConvertFToU`.

use srug_spirv::{kernels, KernelInfo};

/// SPIR-V's `OpConvertFToU`.
const OP_CONVERT_F_TO_U: u32 = 109;

/// How many instructions of `opcode` the module holds.
fn count_opcode(words: &[u32], opcode: u32) -> usize {
    // Past the five-word header, each instruction's first word holds its
    // word count (high half) and opcode (low half).
    let mut at = 5;
    let mut found = 0;
    while at < words.len() {
        let (count, op) = ((words[at] >> 16) as usize, words[at] & 0xffff);
        assert!(count > 0, "an instruction of no words at word {at}");
        found += usize::from(op == opcode);
        at += count;
    }
    assert_eq!(at, words.len(), "the last instruction runs past the module");
    found
}

#[test]
fn per_gaussian_and_per_pair_kernels_convert_no_float_to_unsigned() {
    let hot: [&KernelInfo; 14] = [
        &kernels::SPLAT_PREPROCESS,
        &kernels::SPLAT_PREPROCESS_TEXEL,
        &kernels::SPLAT_KEYS,
        &kernels::SPLAT_KEYS_TEXEL,
        &kernels::SPLAT_RANGES,
        &kernels::SPLAT_RANGES_TEXEL,
        &kernels::SORT_HISTOGRAM,
        &kernels::SORT_HISTOGRAM_BLOCK,
        &kernels::SORT_HISTOGRAM_TEXEL,
        &kernels::SORT_HISTOGRAM_WIDE_TEXEL,
        &kernels::SORT_SCATTER,
        &kernels::SORT_SCATTER_BLOCK,
        &kernels::SORT_SCATTER_TEXEL,
        &kernels::SORT_SCATTER_WIDE_TEXEL,
    ];
    let found: Vec<String> = hot
        .iter()
        .filter_map(|k| {
            let n = count_opcode(k.words, OP_CONVERT_F_TO_U);
            (n > 0).then(|| format!("{}: {n}", k.name))
        })
        .collect();
    assert!(found.is_empty(), "OpConvertFToU in {found:?}: convert whole numbers with `whole_to_uint`");
}

#[test]
fn the_opcode_count_sees_conversions_where_they_are() {
    // A kernel that converts floats to unsigned integers (its depth
    // convention, `uint(pack.depth.x)`), so the count above can fail.
    assert!(count_opcode(kernels::HOST_IMAGE_PACK.words, OP_CONVERT_F_TO_U) > 0);
}
