//! What every plot of host-sim shares: the font ([`init_font`], `$HOST_SIM_FONT` first) and
//! the axis range of a series.

/// The family name the plots' text asks for.
pub const FONT: &str = liftfw_plotfont::FAMILY;

/// Finds and registers the plots' font once (`$HOST_SIM_FONT`, else a system sans-serif
/// face). Errors say how to get one.
pub fn init_font() -> Result<std::path::PathBuf, String> {
    liftfw_plotfont::register("HOST_SIM_FONT")
}

/// The axis range of `values`: their span padded by 6 % (a flat series by 10⁻⁶ of its size, so
/// that it shows); (−1, 1) when none is finite.
pub(crate) fn range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    });
    if !(lo.is_finite() && hi.is_finite()) {
        return (-1.0, 1.0);
    }
    let pad = ((hi - lo) * 0.06)
        .max(1e-6 * hi.abs().max(lo.abs()))
        .max(1e-9);
    (lo - pad, hi + pad)
}
