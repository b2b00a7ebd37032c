//! CPU twins of the GPU passes in [`crate::gpu`]: straightforward versions
//! the GPU results are compared with.

pub mod casters;
pub mod hard_shadows;
pub mod light_view;
pub mod occlusion;
pub mod scan;
pub mod soft;
pub mod texel_lists;
