//! The instruction set this build uses, checked against the CPU it runs on.
//!
//! On x86-64, `.cargo/config.toml` builds plume for **x86-64-v3** (AVX2, FMA, BMI1/2, F16C,
//! LZCNT, MOVBE, on top of SSE4.2 and POPCNT): Intel Haswell (2013), AMD Excavator (2015)
//! and every x86-64 CPU since. The compiler then uses 256-bit vectors and three-operand
//! instructions everywhere. Renders run 7–17 % faster (the trilinear walk's `f64`
//! arithmetic gains most), and the images are bit for bit the same, since Rust never fuses a multiply and an add by
//! itself (docs/BENCHMARKS.md, "Build target").
//!
//! A CPU without one of these features would die of `SIGILL` at the first such instruction.
//! `plume` calls [`missing_features`] first, and refuses to start with one line naming
//! the features and how to rebuild. Only features this build was compiled with are asked
//! for: a build for the baseline (`RUSTFLAGS='-C target-cpu=x86-64'`) asks for nothing.

/// The CPU features this build was compiled to use that the running CPU lacks (empty on
/// a suitable CPU, and on other architectures).
#[must_use]
pub fn missing_features() -> Vec<&'static str> {
    missing_among(&compiled_features(), detected)
}

/// The x86-64-v3 features (and those of v2 below them) this build was compiled with.
#[must_use]
pub fn compiled_features() -> Vec<&'static str> {
    #[allow(unused_mut, reason = "nothing to push outside x86-64")]
    let mut compiled = Vec::new();
    macro_rules! compiled {
        ($($feature:tt),*) => {
            $(if cfg!(target_feature = $feature) {
                compiled.push($feature);
            })*
        };
    }
    compiled!("sse3", "ssse3", "sse4.1", "sse4.2", "popcnt", "avx", "avx2", "fma", "bmi1", "bmi2", "f16c", "lzcnt", "movbe");
    compiled
}

/// Those of `features` that `present` says the CPU lacks.
fn missing_among(features: &[&'static str], present: impl Fn(&str) -> bool) -> Vec<&'static str> {
    features.iter().copied().filter(|f| !present(f)).collect()
}

/// Whether the running CPU has `feature` (cpuid; a name [`compiled_features`] gives).
fn detected(feature: &str) -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::is_x86_feature_detected as has;
        match feature {
            "sse3" => has!("sse3"),
            "ssse3" => has!("ssse3"),
            "sse4.1" => has!("sse4.1"),
            "sse4.2" => has!("sse4.2"),
            "popcnt" => has!("popcnt"),
            "avx" => has!("avx"),
            "avx2" => has!("avx2"),
            "fma" => has!("fma"),
            "bmi1" => has!("bmi1"),
            "bmi2" => has!("bmi2"),
            "f16c" => has!("f16c"),
            "lzcnt" => has!("lzcnt"),
            "movbe" => has!("movbe"),
            _ => false,
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let _ = feature;
        false
    }
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
    /// for is missing here (or this test would have died of SIGILL), and each compiled
    /// feature's name is one the detection knows.
    #[test]
    fn this_machine_has_what_the_build_uses() {
        assert!(missing_features().is_empty(), "{:?}", missing_features());
        for feature in compiled_features() {
            assert!(detected(feature), "{feature}");
        }
    }

    /// A CPU lacking some of the compiled features is refused with exactly those.
    #[test]
    fn a_cpu_without_a_feature_is_found_out() {
        let compiled = ["sse4.2", "avx2", "fma", "bmi2"];
        assert_eq!(missing_among(&compiled, |f| f != "fma" && f != "bmi2"), ["fma", "bmi2"]);
        assert!(missing_among(&compiled, |_| true).is_empty());
    }

    #[test]
    fn the_refusal_names_the_features_and_the_rebuild() {
        let line = refusal(&["avx2", "fma"]);
        assert!(line.contains("avx2, fma") && line.contains("target-cpu=native") && !line.contains('\n'), "{line}");
    }
}
