//! CPU twins of the GPU passes in [`crate::gpu`]: straightforward versions
//! the GPU results are compared with.

pub mod scan;
