//! `StrataBatch` descriptors for the tests: the arrays of either layout as
//! the descriptor's vector fields.

use strata_capi::{StrataVectors, StrataVectorsOut};

/// `3 n` floats, `x, y, z` per query.
pub fn aos(v: &[f32]) -> StrataVectors {
    StrataVectors {
        xyz: v.as_ptr(),
        ..Default::default()
    }
}

/// Three arrays of `n` floats.
pub fn soa3(c: &[Vec<f32>; 3]) -> StrataVectors {
    StrataVectors {
        x: c[0].as_ptr(),
        y: c[1].as_ptr(),
        z: c[2].as_ptr(),
        ..Default::default()
    }
}

/// `3 n` floats to write, three per query.
pub fn aos_out(v: &mut [f32]) -> StrataVectorsOut {
    StrataVectorsOut {
        xyz: v.as_mut_ptr(),
        ..Default::default()
    }
}

/// Three arrays of `n` floats to write.
pub fn soa3_out(c: &mut [Vec<f32>; 3]) -> StrataVectorsOut {
    let [x, y, z] = c;
    StrataVectorsOut {
        x: x.as_mut_ptr(),
        y: y.as_mut_ptr(),
        z: z.as_mut_ptr(),
        ..Default::default()
    }
}
