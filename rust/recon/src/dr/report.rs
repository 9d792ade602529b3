//! The loss curves of a DR run as files: `loss.csv` (one row per step) and `loss.png` (one row of
//! panels per stage: the total loss, and each term on a log axis). Both written atomically.

use std::io::Write;
use std::path::Path;

use hairrecon_core::formats::{atomic_write, FormatError};
use hairrecon_raster::plot::{curve_plot_png, CurvePanel};

use super::{DrStage, LossRecord, LossTerms};

/// The CSV header of [`write_loss_csv`].
pub const CSV_HEADER: &str = "stage,iteration,total,mask,orientation,curvature,length,seconds";

/// Writes `stage,iteration,total,mask,orientation,curvature,length,seconds` (the loss before the
/// step, in the views it rendered, and the step's wall time), one row per step.
pub fn write_loss_csv(path: &Path, records: &[LossRecord]) -> Result<(), FormatError> {
    atomic_write(path, |w| {
        writeln!(w, "{CSV_HEADER}")?;
        for r in records {
            let v = r.terms.values();
            writeln!(
                w,
                "{},{},{},{},{},{},{},{}",
                r.stage,
                r.iteration,
                r.terms.total(),
                v[0],
                v[1],
                v[2],
                v[3],
                r.seconds
            )?;
        }
        Ok(())
    })
}

const TERM_COLOURS: [[u8; 3]; 4] = [[31, 119, 180], [214, 39, 40], [44, 160, 44], [148, 103, 189]];

/// Writes the plot of [`write_loss_csv`]'s data as PNG.
pub fn write_loss_png(path: &Path, records: &[LossRecord]) -> Result<(), FormatError> {
    let mut panels = Vec::new();
    for stage in [DrStage::Guides, DrStage::Children] {
        let terms: Vec<LossTerms> = records.iter().filter(|r| r.stage == stage).map(|r| r.terms).collect();
        if terms.is_empty() {
            continue;
        }
        let name = stage.to_string().to_uppercase();
        panels.push(CurvePanel {
            title: format!("{name}: TOTAL LOSS"),
            curves: vec![("TOTAL".into(), [0, 0, 0], terms.iter().map(|t| t.total() as f32).collect())],
            log_y: false,
        });
        panels.push(CurvePanel {
            title: format!("{name}: TERMS"),
            curves: LossTerms::NAMES
                .iter()
                .zip(TERM_COLOURS)
                .enumerate()
                .map(|(k, (n, c))| (n.to_uppercase(), c, terms.iter().map(|t| t.values()[k] as f32).collect()))
                .collect(),
            log_y: true,
        });
    }
    let png =
        curve_plot_png(&panels, 2, "STEP").map_err(|e| FormatError::from(std::io::Error::other(e.to_string())))?;
    atomic_write(path, |w| Ok(w.write_all(&png)?))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_has_a_header_and_one_row_per_step() {
        let dir = std::env::temp_dir().join(format!("hairrecon-dr-report-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let rec = |stage, iteration, m| LossRecord {
            stage,
            iteration,
            terms: LossTerms { mask: m, orientation: 2.0, curvature: 0.5, length: 0.25 },
            seconds: 1.5,
        };
        let records = [rec(DrStage::Guides, 0, 10.0), rec(DrStage::Guides, 1, 9.0), rec(DrStage::Children, 0, 8.0)];
        write_loss_csv(&dir.join("loss.csv"), &records).unwrap();
        write_loss_png(&dir.join("loss.png"), &records).unwrap();
        let text = std::fs::read_to_string(dir.join("loss.csv")).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], CSV_HEADER);
        assert_eq!(lines[1], "guides,0,12.75,10,2,0.5,0.25,1.5");
        assert_eq!(lines[3], "children,0,10.75,8,2,0.5,0.25,1.5");
        assert_eq!(lines.len(), 4);
        assert!(image::open(dir.join("loss.png")).is_ok());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
