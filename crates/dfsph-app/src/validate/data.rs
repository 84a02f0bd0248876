//! The experimental data, embedded in the binary so `dfsph2d validate` runs anywhere. The
//! files and their sources are in `crates/dfsph-app/data/validation/` (see its README.md):
//! every CSV starts with `#` lines naming its source, then one header line.

/// A parsed data file: column names and columns of numbers.
pub struct Table {
    pub file: &'static str,
    pub columns: Vec<(String, Vec<f64>)>,
}

impl Table {
    fn parse(file: &'static str, text: &str) -> Self {
        let mut lines = text
            .lines()
            .map(str::trim)
            .filter(|l| !l.is_empty() && !l.starts_with('#'));
        let header: Vec<String> = lines
            .next()
            .unwrap_or_default()
            .split(',')
            .map(|s| s.trim().to_string())
            .collect();
        let mut columns: Vec<(String, Vec<f64>)> =
            header.into_iter().map(|h| (h, Vec::new())).collect();
        for line in lines {
            for (k, field) in line.split(',').enumerate() {
                if let Some(col) = columns.get_mut(k) {
                    col.1.push(field.trim().parse().unwrap_or(f64::NAN));
                }
            }
        }
        Self { file, columns }
    }

    /// The column called `name`. Panics on a missing column: the data is embedded, so that
    /// is a programming error caught by the tests.
    pub fn col(&self, name: &str) -> &[f64] {
        self.columns
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, c)| c.as_slice())
            .unwrap_or_else(|| panic!("{}: no column {name}", self.file))
    }

    /// Rows where column `key` equals `value`, as (x, y) pairs of two other columns.
    pub fn pairs_where(&self, key: &str, value: f64, x: &str, y: &str) -> Vec<(f64, f64)> {
        let k = self.col(key);
        self.col(x)
            .iter()
            .zip(self.col(y))
            .zip(k)
            .filter(|(_, &kv)| (kv - value).abs() < 1e-9)
            .map(|((&a, &b), _)| (a, b))
            .collect()
    }

    /// Two columns as (x, y) pairs, rows with a non-finite value dropped.
    pub fn pairs(&self, x: &str, y: &str) -> Vec<(f64, f64)> {
        self.col(x)
            .iter()
            .zip(self.col(y))
            .filter(|(a, b)| a.is_finite() && b.is_finite())
            .map(|(&a, &b)| (a, b))
            .collect()
    }
}

macro_rules! embedded {
    ($fn:ident, $file:literal) => {
        pub fn $fn() -> Table {
            Table::parse(
                $file,
                include_str!(concat!("../../data/validation/", $file)),
            )
        }
    };
}

// Martin & Moyce (1952), Table 2: surge front, n² = 2, a = 2.25 in. T = t·√(2g/a), Z = x/a.
embedded!(mm_front_table2, "martin_moyce_1952_front_n2_a2p25in.csv");
// Martin & Moyce (1952), Fig. 3: surge front for a = 1.125 in and 2.25 in, up to Z = 14.
embedded!(mm_front_fig3, "martin_moyce_1952_front_n2_fig3_long.csv");
// Martin & Moyce (1952), Table 6: residual column height. τ = t·√(g/a), H = h/(2a).
embedded!(mm_height_table6, "martin_moyce_1952_height_n2_a2p25in.csv");
// Koshizuka & Oka (1996), experiment: surge front. T = t·√(2g/L), Z = x/L.
embedded!(ko_front, "koshizuka_oka_1996_front_exp.csv");
// Lobovsky et al. (2014), H = 300 mm: water levels h/H at four gauges against T = t·√(g/H).
embedded!(lobovsky_levels, "lobovsky_2014_H300_water_levels.csv");
// Lobovsky et al. (2014), H = 300 mm: far-wall pressure P = p/(ρgH) against T = t·√(g/H).
embedded!(
    lobovsky_pressure,
    "lobovsky_2014_H300_pressure_decimated.csv"
);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_file_parses_with_its_columns() {
        assert_eq!(mm_front_table2().pairs("T", "Z").len(), 15);
        assert_eq!(
            mm_front_fig3().pairs_where("a_inch", 2.25, "T", "Z").len(),
            15
        );
        assert_eq!(mm_height_table6().pairs("tau", "H").len(), 17);
        assert_eq!(ko_front().pairs("T", "Z").len(), 9);
        let levels = lobovsky_levels();
        assert!(levels.col("T").len() > 500);
        assert!(levels.col("h_H4_5").iter().all(|v| v.is_finite()));
        let p = lobovsky_pressure();
        assert!(p.col("p_s4").len() > 2000);
    }
}
