//! A readable text table of an [`EvalReport`].

use std::fmt::Write;

use super::report::EvalReport;

/// Formats every figure of `report` as an aligned text table.
pub fn report_table(report: &EvalReport) -> String {
    let mut s = String::new();
    // Writing to a String cannot fail.
    let _ = write_table(&mut s, report);
    s
}

fn write_table(s: &mut String, r: &EvalReport) -> std::fmt::Result {
    writeln!(
        s,
        "poses: {} reference, {} estimate, {} matched; ground-truth path {:.3} m",
        r.reference_poses, r.estimate_poses, r.matched_poses, r.path_length_m
    )?;
    match &r.kitti {
        Some(k) => {
            writeln!(s, "\nKITTI odometry metric ({} segments)", k.segments)?;
            writeln!(
                s,
                "  {:>8}  {:>8}  {:>10}  {:>12}  {:>14}",
                "length", "segments", "t_err [%]", "r_err [deg/m]", "r_err [deg/100m]"
            )?;
            for l in &k.per_length {
                writeln!(
                    s,
                    "  {:>8.0}  {:>8}  {:>10.4}  {:>12.6}  {:>14.4}",
                    l.length, l.segments, l.t_err_pct, l.r_err_deg_per_m, l.r_err_deg_per_100m
                )?;
            }
            writeln!(
                s,
                "  {:>8}  {:>8}  {:>10.4}  {:>12.6}  {:>14.4}",
                "all", k.segments, k.t_err_pct, k.r_err_deg_per_m, k.r_err_deg_per_100m
            )?;
        }
        None => writeln!(
            s,
            "\nKITTI odometry metric: no 100 m segment fits the ground truth"
        )?,
    }
    writeln!(s, "\nATE [m]")?;
    writeln!(
        s,
        "  {:<10} {:>10} {:>10} {:>10} {:>10} {:>10} {:>10} {:>8}",
        "alignment", "rmse", "mean", "median", "std", "min", "max", "scale"
    )?;
    for (name, st, scale) in [
        ("none", &r.ate.none, 1.0),
        ("se3", &r.ate.se3, 1.0),
        ("sim3", &r.ate.sim3, r.ate.sim3_scale),
    ] {
        writeln!(
            s,
            "  {:<10} {:>10.4} {:>10.4} {:>10.4} {:>10.4} {:>10.4} {:>10.4} {:>8.4}",
            name, st.rmse, st.mean, st.median, st.std, st.min, st.max, scale
        )?;
    }
    writeln!(s, "\nRPE")?;
    writeln!(
        s,
        "  {:<12} {:>7} {:>10} {:>10} {:>10} {:>10} {:>10} {:>10}",
        "delta", "pairs", "t_rmse[m]", "t_mean", "t_max", "r_rmse[°]", "r_mean", "r_max"
    )?;
    for (key, p) in &r.rpe {
        writeln!(
            s,
            "  {:<12} {:>7} {:>10.4} {:>10.4} {:>10.4} {:>10.4} {:>10.4} {:>10.4}",
            key,
            p.pairs,
            p.trans_rmse,
            p.trans_mean,
            p.trans_max,
            p.rot_rmse_deg,
            p.rot_mean_deg,
            p.rot_max_deg
        )?;
    }
    Ok(())
}
