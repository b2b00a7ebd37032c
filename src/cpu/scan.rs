//! CPU twin of [`crate::gpu::scan`].

/// Exclusive prefix sum of `input` and the total, with the GPU's wrapping
/// 32-bit arithmetic: `out[i] = input[0] + ... + input[i - 1]`.
pub fn exclusive_scan(input: &[u32]) -> (Vec<u32>, u32) {
    let mut out = Vec::with_capacity(input.len());
    let mut sum = 0u32;
    for &x in input {
        out.push(sum);
        sum = sum.wrapping_add(x);
    }
    (out, sum)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn small() {
        assert_eq!(exclusive_scan(&[]), (vec![], 0));
        assert_eq!(exclusive_scan(&[5]), (vec![0], 5));
        assert_eq!(exclusive_scan(&[1, 2, 3, 4]), (vec![0, 1, 3, 6], 10));
        assert_eq!(exclusive_scan(&[u32::MAX, 2]), (vec![0, u32::MAX], 1));
    }
}
