//! The checks of a tabulated spectrum in a material: its wavelengths, and
//! each value against the rule of its field.
//!
//! A field's rule is the one its RGB numbers obey (an albedo in [0, 1], an
//! extinction `>= 0`, ...), applied at every sample, so that any value of the
//! spectrum, at any wavelength, is one the field accepts; its RGB numbers,
//! clamped to the range of its values, are then valid too.

use super::error::StackError;

/// Checks the samples `(nm[i], values[i])` of the spectrum given for
/// `field`: at least one, one value per wavelength, wavelengths finite and
/// strictly increasing, and every value accepted by `rule` (which returns
/// the problem with a value, or `None`). Errors name the field, the sample's
/// index and its value: `interface.albedo.values[2] = 1.5: must be in [0, 1]`.
pub(super) fn check_samples(
    layer: Option<usize>,
    field: &str,
    nm: &[f64],
    values: &[f64],
    rule: impl Fn(f64) -> Option<String>,
) -> Result<(), StackError> {
    if nm.is_empty() {
        return Err(StackError::msg(
            layer,
            &format!("{field}.nm"),
            "the spectrum has no samples: give at least one wavelength and its value",
        ));
    }
    if nm.len() != values.len() {
        return Err(StackError::msg(
            layer,
            &format!("{field}.values"),
            &format!(
                "{} values for {} wavelengths: give one value per wavelength of `nm`",
                values.len(),
                nm.len()
            ),
        ));
    }
    for (i, &w) in nm.iter().enumerate() {
        let at = format!("{field}.nm[{i}]");
        if !w.is_finite() {
            return Err(StackError::new(layer, &at, w, "must be a finite number"));
        }
        if i > 0 && w <= nm[i - 1] {
            return Err(StackError::new(
                layer,
                &at,
                w,
                &format!(
                    "the wavelengths must be strictly increasing (nm[{}] = {})",
                    i - 1,
                    nm[i - 1]
                ),
            ));
        }
    }
    for (i, &v) in values.iter().enumerate() {
        if let Some(problem) = rule(v) {
            return Err(StackError::new(
                layer,
                &format!("{field}.values[{i}]"),
                v,
                &problem,
            ));
        }
    }
    Ok(())
}
