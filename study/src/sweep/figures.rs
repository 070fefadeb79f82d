//! The paper's figures 4-11 from the sweep's rows: stage times against nodes per cache
//! size (figs. 4-7), the cache hit ratio against cache size with the most nodes (fig. 8,
//! drawn as the blocks fetched per read on a log axis: the miss ratio 1 - hit, plus the
//! blocks our scheme fetches ahead), and the speed-up T(n0)/T(n) of the
//! total, LRT and VRT with the linear line (figs. 9-11), one set per schedule.

use super::run::Row;
use crate::error::Result;
use crate::plot::{Plot, Series, PALETTE};
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

fn distinct<T: Ord + Copy>(rows: &[Row], f: impl Fn(&Row) -> T) -> Vec<T> {
    rows.iter().map(f).collect::<BTreeSet<_>>().into_iter().collect()
}

fn color(i: usize) -> [u8; 3] {
    PALETTE[i % PALETTE.len()]
}

/// The rows of one (schedule, forks, cache) line, ascending in nodes; a schedule is a
/// scheme, with its acceleration structure when that is not the grid (`Shape::schedule`).
fn line<'a>(rows: &'a [Row], scheme: &str, forks: u32, cache: u32) -> Vec<&'a Row> {
    let mut v: Vec<&Row> = rows
        .iter()
        .filter(|r| r.shape.schedule() == scheme && r.shape.forks == forks && r.shape.cache_blocks == cache)
        .collect();
    v.sort_by_key(|r| r.shape.nodes);
    v
}

/// Writes every figure into `dir`; returns the files written.
pub fn write_all(rows: &[Row], dir: &Path) -> Result<Vec<PathBuf>> {
    let mut written = Vec::new();
    let schemes: Vec<String> = rows.iter().map(|r| r.shape.schedule()).collect::<BTreeSet<_>>().into_iter().collect();
    let caches = distinct(rows, |r| r.shape.cache_blocks);
    let forks_all = distinct(rows, |r| r.shape.forks);
    let Some(&forks) = forks_all.iter().max() else { return Ok(written) };
    let mut save = |plot: Plot, name: String| -> Result<()> {
        let path = dir.join(name);
        plot.write(&path)?;
        written.push(path);
        Ok(())
    };
    for scheme in &schemes {
        // Figures 4-7: rendering time per stage against nodes, one figure per cache size.
        for &cache in &caches {
            let l = line(rows, scheme, forks, cache);
            if l.is_empty() {
                continue;
            }
            let mut plot = Plot::new(
                format!("Rendering time, cache {cache} blocks ({scheme} scheme)"),
                "Node processors",
                "Modelled seconds",
            );
            let stages = [
                ("total_s", "total"),
                ("lrt_s", "LRT"),
                ("vrt_s", "VRT"),
                ("preprocess_s", "preprocessing"),
                ("interp_s", "interpolation"),
            ];
            for (i, (stage, label)) in stages.into_iter().enumerate() {
                let pts = l.iter().map(|r| (r.shape.nodes as f64, r.num(stage))).collect();
                plot.series.push(Series::new(label, pts, color(i)));
            }
            save(plot, format!("time-cache{cache}-{scheme}.png"))?;
        }
        // Figures 9-11: speed-up T(n0)/T(n) per cache size, with the linear line.
        for (stage, what) in
            [("total_s", "total"), ("lrt_s", "light ray tracing (LRT)"), ("vrt_s", "viewing ray tracing (VRT)")]
        {
            let mut plot = Plot::new(format!("Speed-up, {what} ({scheme} scheme)"), "Node processors", "T(n0) / T(n)");
            let mut n0_all = BTreeSet::new();
            for (i, &cache) in caches.iter().enumerate() {
                let l = line(rows, scheme, forks, cache);
                let Some(first) = l.first() else { continue };
                let t0 = first.num(stage);
                n0_all.insert(first.shape.nodes);
                let pts = l.iter().map(|r| (r.shape.nodes as f64, t0 / r.num(stage))).collect();
                plot.series.push(Series::new(format!("cache {cache}"), pts, color(i)));
            }
            if let (Some(&n0), Some(nmax)) = (n0_all.iter().next(), rows.iter().map(|r| r.shape.nodes).max()) {
                let (n0, nmax) = (n0 as f64, nmax as f64);
                let mut linear = Series::new("linear", vec![(n0, 1.0), (nmax, nmax / n0)], [0, 0, 0]);
                linear.markers = false;
                plot.series.push(linear);
            }
            save(plot, format!("speedup-{}-{scheme}.png", stage.trim_end_matches("_s")))?;
        }
    }
    // Figure 8: the cache's miss ratio with the most nodes, per schedule, counting the
    // blocks our scheme fetches ahead of a read as misses (every block fetched).
    if let Some(nmax) = rows.iter().map(|r| r.shape.nodes).max() {
        let mut plot = Plot::new(
            format!("Blocks fetched per cache read (misses and blocks fetched ahead), {nmax} nodes"),
            "Cache blocks per node",
            "Fetched per read",
        );
        for (i, scheme) in schemes.iter().enumerate() {
            let mut pts: Vec<(f64, f64)> = rows
                .iter()
                .filter(|r| &r.shape.schedule() == scheme && r.shape.nodes == nmax && r.shape.forks == forks)
                .map(|r| (r.shape.cache_blocks as f64, r.fetched_per_read()))
                .collect();
            pts.sort_by(|a, b| a.0.total_cmp(&b.0));
            plot.series.push(Series::new(format!("{scheme} scheme"), pts, color(i)));
        }
        save(plot, "hit-ratio.png".to_string())?;
    }
    Ok(written)
}
