//! CPU twin of [`crate::gpu::visibility_out`]: the `f32` a caller's target
//! receives per view sample from the resolve pass's result words.

/// Per view sample: hard (`soft == false`), 1 where the resolve flags say
/// evaluated and lit (bits 1 and 0), else 0; soft, the fraction (the
/// word's `f32` bits), 0 where negative (not evaluated).
pub fn visibility_out(result: &[u32], soft: bool) -> Vec<f32> {
    result
        .iter()
        .map(|&r| {
            if soft {
                f32::from_bits(r).max(0.0)
            } else if r & 3 == 3 {
                1.0
            } else {
                0.0
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::visibility_out;

    #[test]
    fn hard_and_soft_words() {
        assert_eq!(visibility_out(&[0, 1, 2, 3], false), [0.0, 0.0, 0.0, 1.0]);
        let words = [(-1.0f32).to_bits(), 0.25f32.to_bits(), 1.0f32.to_bits()];
        assert_eq!(visibility_out(&words, true), [0.0, 0.25, 1.0]);
    }
}
