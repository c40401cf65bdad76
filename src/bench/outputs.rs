//! How a [`CompareReport`] is shown and stored: Markdown tables (the terminal and
//! `docs/BENCHMARKS.md` print the same), a long-format CSV, JSON, and PNG plots.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::compare::{CompareReport, Point};
use super::numbers::{num, pm, pm_count};
use plume_core::error::{Error, Result};

fn mib(b: u64) -> String {
    format!("{:.0}", b as f64 / 1048576.0)
}

impl CompareReport {
    /// The equal-time table (Markdown).
    #[must_use]
    pub fn equal_time_table(&self) -> String {
        let mut s = String::new();
        let base = &self.methods[0];
        let _ = writeln!(
            s,
            "| method | CPU s | spp | RMSE | RMSE / {} | relMSE | bias | samples / CPU s | core-h | efficiency vs {} | peak RSS MiB |",
            base.method, base.method
        );
        let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|---|");
        for m in &self.methods {
            let e = &m.equal_time;
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {:.3} | {} | {} | {} | {} | {:.2}× | {} |",
                m.method,
                pm(&e.cpu_seconds),
                pm_count(&e.spp),
                pm(&e.rmse),
                e.rmse.mean / base.equal_time.rmse.mean,
                pm(&e.relmse),
                pm(&e.bias),
                num(m.samples_per_cpu_second.mean),
                num(e.cpu_seconds.mean / 3600.0),
                self.efficiency(m),
                mib(m.peak_rss_bytes),
            );
        }
        s
    }

    /// The equal-spp table (Markdown).
    #[must_use]
    pub fn equal_spp_table(&self) -> String {
        let mut s = String::new();
        let base = &self.methods[0];
        let _ = writeln!(
            s,
            "| method | spp | CPU s | core-h | RMSE | RMSE / {} | relMSE | bias |",
            base.method
        );
        let _ = writeln!(s, "|---|---|---|---|---|---|---|---|");
        for m in &self.methods {
            let e = &m.equal_spp;
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {:.3} | {} | {} |",
                m.method,
                self.equal_spp,
                pm(&e.cpu_seconds),
                num(e.cpu_seconds.mean / 3600.0),
                pm(&e.rmse),
                e.rmse.mean / base.equal_spp.rmse.mean,
                pm(&e.relmse),
                pm(&e.bias),
            );
        }
        s
    }

    /// CPU time and core-hours to each target relative RMSE, per method, uniform and (with
    /// `--adaptive`) adaptive (Markdown; `~` marks a time extrapolated at `t^(−1/2)` past
    /// the measured curve).
    #[must_use]
    pub fn target_table(&self) -> String {
        let mut s = String::new();
        let heads: Vec<String> =
            super::targets::TARGETS.iter().map(|t| format!("CPU s to relRMSE {t}")).collect();
        let _ = writeln!(
            s,
            "| method | sampling | {} | core-h to {} |",
            heads.join(" | "),
            super::targets::TARGETS[2]
        );
        let _ = writeln!(s, "|---|---|{}---|", "---|".repeat(heads.len()));
        let cell = |t: &super::targets::TimeToError| match t.cpu_seconds {
            Some(c) if t.extrapolated => format!("~{}", num(c)),
            Some(c) => num(c),
            None => "–".into(),
        };
        for m in &self.methods {
            for (label, times) in [("uniform", &m.to_target), ("adaptive", &m.adaptive_to_target)] {
                if times.is_empty() {
                    continue;
                }
                let cells: Vec<String> = times.iter().map(cell).collect();
                let hours = times
                    .last()
                    .and_then(|t| t.cpu_seconds)
                    .map_or("–".into(), |c| num(c / 3600.0));
                let _ = writeln!(s, "| {} | {label} | {} | {hours} |", m.method, cells.join(" | "));
            }
        }
        s
    }

    /// Each adaptive render against uniform sampling at the same CPU time, per method
    /// (Markdown; empty without `--adaptive`): the measured relative RMSE, the render's own
    /// estimate of it, and the uniform curve's relative RMSE at that CPU time (`~`:
    /// extrapolated at `t^(−1/2)`).
    #[must_use]
    pub fn adaptive_table(&self) -> String {
        let mut s = String::new();
        if self.methods.iter().all(|m| m.adaptive.is_empty()) {
            return s;
        }
        let _ = writeln!(s, "| method | threshold | CPU s | mean spp | pixels at the cap | relRMSE | estimated | uniform at that CPU | adaptive ÷ uniform |");
        let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|");
        for m in &self.methods {
            let uniform: Vec<super::targets::CurvePoint> =
                m.curve.iter().map(Point::curve_point).collect();
            for a in &m.adaptive {
                let at = super::targets::error_at(&uniform, a.point.cpu_seconds);
                let (u, ratio) = at.map_or(("–".into(), "–".into()), |u| {
                    let mark = if u.extrapolated { "~" } else { "" };
                    (
                        format!("{mark}{}", num(u.rel_rmse)),
                        format!("{mark}{:.2}", a.point.rel_rmse / u.rel_rmse),
                    )
                });
                let _ = writeln!(
                    s,
                    "| {} | {} | {} | {:.1} | {} | {} | {} | {u} | {ratio} |",
                    m.method,
                    a.threshold,
                    num(a.point.cpu_seconds),
                    a.mean_spp,
                    a.pixels_at_cap,
                    num(a.point.rel_rmse),
                    a.estimated_rel_rmse.map_or("–".into(), num),
                );
            }
        }
        s
    }

    /// Cost of the light structures per method (Markdown).
    #[must_use]
    pub fn cost_table(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "| method | proxy | light build s | scene heap MiB | peak RSS MiB | non-finite samples |");
        let _ = writeln!(s, "|---|---|---|---|---|---|");
        for m in &self.methods {
            let proxy = m.proxy_resolution.map_or("–".into(), |p| format!("{p}³"));
            let _ = writeln!(
                s,
                "| {} | {} | {:.3} | {} | {} | {} |",
                m.method,
                proxy,
                m.light_build_seconds,
                mib(m.scene_bytes),
                mib(m.peak_rss_bytes),
                m.nonfinite_samples
            );
        }
        s
    }

    /// One paragraph on the setup: scene, flags, reference, budgets, ε.
    #[must_use]
    pub fn setup(&self) -> String {
        let r = &self.reference;
        let noise = r.noise_rmse.map_or(String::new(), |n| {
            format!(
                " Its own estimated RMSE is {} ({:.1} % of the smallest method RMSE at equal time; included in every RMSE below).",
                num(n),
                100.0 * n / self.methods.iter().map(|m| m.equal_time.rmse.mean).fold(f64::INFINITY, f64::min)
            )
        });
        format!(
            "Scene `{}` with `{}`, {}x{}, {} threads, {}. {} runs (seeds) per method of {} CPU s each; equal spp = {}. \
             Reference: {}.{} relMSE: ε = {}, top {} % of pixel errors trimmed. Mean reference value {}.",
            self.scene,
            self.flags.join(" "),
            self.width,
            self.height,
            self.threads,
            if self.emission_only { "emission–absorption only" } else { "scattering" },
            self.runs,
            num(self.cpu_seconds_per_run),
            self.equal_spp,
            r.description,
            noise,
            self.relmse_epsilon,
            self.relmse_trim * 100.0,
            num(self.reference_mean),
        )
    }

    /// Long-format CSV: one row per method and point (`equal-time`, `equal-spp`,
    /// `curve`).
    #[must_use]
    pub fn to_csv(&self) -> String {
        let mut s = String::from("scene,method,point,target,cpu_s_mean,cpu_s_std,spp_mean,spp_std,rmse_mean,rmse_std,relmse_mean,relmse_std,bias_mean,bias_std,samples_per_cpu_s,core_hours,light_build_s,peak_rss_bytes,runs\n");
        for m in &self.methods {
            let mut row = |point: &str, target: f64, p: &Point| {
                let _ = writeln!(
                    s,
                    "{},{},{point},{target},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
                    csv_field(&self.scene),
                    csv_field(&m.method),
                    p.cpu_seconds.mean,
                    p.cpu_seconds.std,
                    p.spp.mean,
                    p.spp.std,
                    p.rmse.mean,
                    p.rmse.std,
                    p.relmse.mean,
                    p.relmse.std,
                    p.bias.mean,
                    p.bias.std,
                    m.samples_per_cpu_second.mean,
                    p.cpu_seconds.mean / 3600.0,
                    m.light_build_seconds,
                    m.peak_rss_bytes,
                    self.runs
                );
            };
            row("equal-time", self.cpu_seconds_per_run, &m.equal_time);
            row("equal-spp", self.equal_spp as f64, &m.equal_spp);
            for (t, p) in self.curve_cpu_seconds.iter().zip(&m.curve) {
                row("curve", *t, p);
            }
        }
        s
    }

    /// Write `NAME.csv`, `NAME.json`, `NAME-error.png` (error vs CPU time) and, with
    /// `crops`, `NAME-crops.png` (crop montage) into `dir`; returns the paths written.
    ///
    /// # Errors
    /// A file cannot be written.
    pub fn write(&self, dir: &Path, name: &str, crops: bool) -> Result<Vec<PathBuf>> {
        std::fs::create_dir_all(dir)
            .map_err(|source| Error::Write { path: dir.to_path_buf(), source })?;
        let csv = dir.join(format!("{name}.csv"));
        plume_core::fs::write_atomic(&csv, |w| {
            std::io::Write::write_all(w, self.to_csv().as_bytes())
        })?;
        let json = dir.join(format!("{name}.json"));
        let text = serde_json::to_string_pretty(self).map_err(|e| Error::Scene(e.to_string()))?;
        plume_core::fs::write_atomic(&json, |w| std::io::Write::write_all(w, text.as_bytes()))?;
        let plot = dir.join(format!("{name}-error.png"));
        super::plot::error_vs_time(self, &plot)?;
        let mut files = vec![csv, json, plot];
        if crops {
            let path = dir.join(format!("{name}-crops.png"));
            super::plot::crop_montage(self, &path)?;
            files.push(path);
        }
        Ok(files)
    }
}

impl std::fmt::Display for CompareReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(f, "{}\n", self.setup())?;
        writeln!(f, "Equal CPU time ({} CPU s per run):\n", num(self.cpu_seconds_per_run))?;
        writeln!(f, "{}", self.equal_time_table())?;
        writeln!(f, "Equal spp ({} spp):\n", self.equal_spp)?;
        writeln!(f, "{}", self.equal_spp_table())?;
        writeln!(
            f,
            "CPU time to a target error (relRMSE = √relMSE; ~: extrapolated at t^(−1/2)):\n"
        )?;
        writeln!(f, "{}", self.target_table())?;
        let adaptive = self.adaptive_table();
        if !adaptive.is_empty() {
            writeln!(f, "Adaptive renders against uniform sampling at equal CPU:\n")?;
            writeln!(f, "{adaptive}")?;
        }
        write!(f, "{}", self.cost_table())
    }
}

/// Quote a CSV field when it holds a comma or quote.
fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_fields_with_commas_are_quoted() {
        assert_eq!(csv_field("a,b"), "\"a,b\"");
    }
}
