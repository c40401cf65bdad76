//! The instruction set this build uses, checked against the CPU it runs on.
//!
//! On x86-64, `.cargo/config.toml` builds plume for **x86-64-v3** (AVX2, FMA, BMI1/2, F16C,
//! LZCNT, MOVBE, on top of SSE4.2 and POPCNT): Intel Haswell (2013), AMD Excavator (2015)
//! and every x86-64 CPU since. The compiler then uses 256-bit vectors and three-operand
//! instructions everywhere. Renders run faster (the trilinear walk's `f64` arithmetic gains
//! most), and the images are bit
//! for bit the same, since Rust never fuses a multiply and an add by itself.
//!
//! A CPU without one of these features would die of `SIGILL` at the first such instruction.
//! `plume` calls [`missing_features`] first, and refuses to start with one line naming
//! the features and how to rebuild. Only features this build was compiled with are asked
//! for: a build for the baseline (`RUSTFLAGS='-C target-cpu=x86-64'`) asks for nothing.

/// One x86-64-v3 feature (or a v2 feature below them): its name, whether this build was
/// compiled to use it, and the running CPU's answer (cpuid).
struct Feature {
    name: &'static str,
    compiled: bool,
    detected: fn() -> bool,
}

#[cfg(target_arch = "x86_64")]
macro_rules! features {
    ($($name:tt),*) => {
        &[$(Feature { name: $name, compiled: cfg!(target_feature = $name), detected: || std::arch::is_x86_feature_detected!($name) }),*]
    };
}

/// The features [`missing_features`] checks.
#[cfg(target_arch = "x86_64")]
const FEATURES: &[Feature] = features!(
    "sse3", "ssse3", "sse4.1", "sse4.2", "popcnt", "avx", "avx2", "fma", "bmi1", "bmi2", "f16c",
    "lzcnt", "movbe"
);
#[cfg(not(target_arch = "x86_64"))]
const FEATURES: &[Feature] = &[];

/// The CPU features this build was compiled to use that the running CPU lacks (empty on
/// a suitable CPU, and on other architectures).
#[must_use]
pub fn missing_features() -> Vec<&'static str> {
    missing_among(FEATURES)
}

/// The names of `features` compiled in and not detected.
fn missing_among(features: &[Feature]) -> Vec<&'static str> {
    features.iter().filter(|f| f.compiled && !(f.detected)()).map(|f| f.name).collect()
}

/// The one-line refusal for a CPU lacking `missing` (see [`missing_features`]).
#[must_use]
pub fn refusal(missing: &[&str]) -> String {
    format!(
        "this CPU lacks {}, which this build of plume was compiled to use (x86-64-v3 unless RUSTFLAGS said otherwise: .cargo/config.toml); rebuild for this CPU with RUSTFLAGS='-C target-cpu=native' cargo build --release",
        missing.join(", ")
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The machine that runs the tests runs the build's code: nothing it was compiled
    /// for is missing here (or this test would have died of SIGILL).
    #[test]
    fn this_machine_has_what_the_build_uses() {
        assert!(missing_features().is_empty(), "{:?}", missing_features());
    }

    /// A CPU lacking some of the compiled features is refused with exactly those; a
    /// feature the build does not use is never asked for.
    #[test]
    fn a_cpu_without_a_feature_is_found_out() {
        let feature = |name, compiled, detected: fn() -> bool| Feature { name, compiled, detected };
        let features = [
            feature("sse4.2", true, || true),
            feature("avx2", true, || true),
            feature("fma", true, || false),
            feature("bmi2", true, || false),
            feature("movbe", false, || false),
        ];
        assert_eq!(missing_among(&features), ["fma", "bmi2"]);
        assert!(missing_among(&features[..2]).is_empty());
    }

    #[test]
    fn the_refusal_names_the_features_and_the_rebuild() {
        let line = refusal(&["avx2", "fma"]);
        assert!(
            line.contains("avx2, fma")
                && line.contains("target-cpu=native")
                && !line.contains('\n'),
            "{line}"
        );
    }
}
