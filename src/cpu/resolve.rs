//! CPU twin of the resolve passes (`resolve_hard.comp`, `resolve_soft.comp`):
//! per view sample, whether it was evaluated and its visibility.

use glam::Vec3;

use super::texel_lists::NOT_LISTED;

/// Hard shadows: per view sample, `None` where it was not listed (no
/// sample, or facing away from the light), else whether it is lit: its
/// list slot's shadow flag is clear.
pub fn resolve_hard(
    sample_texel: &[u32],
    sample_slot: &[u32],
    shadowed: &[u32],
) -> Vec<Option<bool>> {
    sample_texel
        .iter()
        .zip(sample_slot)
        .map(|(&t, &slot)| (t != NOT_LISTED).then(|| shadowed[slot as usize] == 0))
        .collect()
}

/// Soft shadows of one view sample at camera-relative `position` with unit
/// `normal`, listed at `slot` with `blocked` light samples (`words` words
/// per slot): its visible light samples, those in front of its surface (the
/// oracle's normal rule, in f32 as the shader computes it) and not
/// blocked, `words` words; and their share of the light's samples.
pub fn resolve_soft(
    position: Vec3,
    normal: Vec3,
    blocked: &[u32],
    light_samples: &[Vec3],
) -> (Vec<u32>, f32) {
    let words = blocked.len();
    let mut visible = vec![0u32; words];
    let mut total = 0;
    for (w, v) in visible.iter_mut().enumerate() {
        let mut front = 0u32;
        for b in 0..32 {
            let j = w * 32 + b;
            if j < light_samples.len() && normal.dot(light_samples[j] - position) > 0.0 {
                front |= 1 << b;
            }
        }
        *v = front & !blocked[w];
        total += v.count_ones();
    }
    (visible, total as f32 / light_samples.len() as f32)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hard_resolve_reads_the_slot_flag() {
        let lit = resolve_hard(&[3, NOT_LISTED, 0], &[1, 0, 0], &[1, 0]);
        assert_eq!(lit, vec![Some(true), None, Some(false)]);
    }

    #[test]
    fn soft_resolve_applies_the_normal_rule() {
        // Two samples above the surface, one below; the first is blocked.
        let samples = [Vec3::Y, Vec3::new(0.5, 1.0, 0.0), -Vec3::Y];
        let (visible, v) = resolve_soft(Vec3::ZERO, Vec3::Y, &[1, 0, 0, 0], &samples);
        assert_eq!(visible, vec![0b010, 0, 0, 0]);
        assert_eq!(v, 1.0 / 3.0);
    }
}
