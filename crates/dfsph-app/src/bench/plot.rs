//! The benchmark plot: nanoseconds per particle-step against particle count, log–log, one line
//! per code and thread count. Plain SVG written by hand: no dependency, text stays text.

use std::fmt::Write;

use super::types::{Code, Row};

const W: f64 = 720.0;
const H: f64 = 460.0;
const LEFT: f64 = 80.0;
const RIGHT: f64 = 200.0;
const TOP: f64 = 40.0;
const BOTTOM: f64 = 60.0;

/// One line: (code, threads) and its points (n, ns per particle-step) sorted by n.
type Series = ((Code, usize), Vec<(f64, f64)>);

/// The SVG document.
pub fn svg(rows: &[Row]) -> String {
    // Series: (code, threads) → points sorted by n.
    let mut keys: Vec<(Code, usize)> = rows.iter().map(|r| (r.code, r.threads)).collect();
    keys.sort();
    keys.dedup();
    let series: Vec<Series> = keys
        .iter()
        .map(|&k| {
            let mut pts: Vec<(f64, f64)> = rows
                .iter()
                .filter(|r| (r.code, r.threads) == k && r.n > 0 && r.ns_per_particle_step > 0.0)
                .map(|r| (r.n as f64, r.ns_per_particle_step))
                .collect();
            pts.sort_by(|a, b| a.0.total_cmp(&b.0));
            (k, pts)
        })
        .filter(|(_, p)| !p.is_empty())
        .collect();
    let all = series.iter().flat_map(|(_, p)| p.iter());
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for &(x, y) in all {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    if x0 > x1 {
        (x0, x1, y0, y1) = (1.0e3, 1.0e6, 10.0, 1.0e4);
    }
    // Whole decades around the data.
    let (lx0, lx1) = ((x0.log10() - 0.05).floor(), (x1.log10() + 0.05).ceil());
    let (ly0, ly1) = ((y0.log10() - 0.05).floor(), (y1.log10() + 0.05).ceil());
    let px = |x: f64| LEFT + (x.log10() - lx0) / (lx1 - lx0) * (W - LEFT - RIGHT);
    let py = |y: f64| H - BOTTOM - (y.log10() - ly0) / (ly1 - ly0) * (H - TOP - BOTTOM);

    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" viewBox="0 0 {W} {H}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(s, r#"<rect width="{W}" height="{H}" fill="white"/>"#);
    let _ = writeln!(
        s,
        r#"<text x="{}" y="22" text-anchor="middle" font-size="15">Dam break: wall time per particle-step</text>"#,
        (LEFT + W - RIGHT) / 2.0
    );
    // Grid and tick labels: decades labelled, 2 and 5 as light lines.
    for d in lx0 as i32..=lx1 as i32 {
        for m in [1.0, 2.0, 5.0] {
            let x = m * 10f64.powi(d);
            if x.log10() > lx1 + 1e-9 {
                continue;
            }
            let gx = px(x);
            let stroke = if m == 1.0 { "#bbb" } else { "#eee" };
            let _ = writeln!(
                s,
                r#"<line x1="{gx:.1}" y1="{TOP}" x2="{gx:.1}" y2="{:.1}" stroke="{stroke}"/>"#,
                H - BOTTOM
            );
            let _ = writeln!(
                s,
                r#"<text x="{gx:.1}" y="{:.1}" text-anchor="middle">{}</text>"#,
                H - BOTTOM + 16.0,
                count_label(x)
            );
        }
    }
    for d in ly0 as i32..=ly1 as i32 {
        for m in [1.0, 2.0, 5.0] {
            let y = m * 10f64.powi(d);
            if y.log10() > ly1 + 1e-9 {
                continue;
            }
            let gy = py(y);
            let stroke = if m == 1.0 { "#bbb" } else { "#eee" };
            let _ = writeln!(
                s,
                r#"<line x1="{LEFT}" y1="{gy:.1}" x2="{:.1}" y2="{gy:.1}" stroke="{stroke}"/>"#,
                W - RIGHT
            );
            let _ = writeln!(
                s,
                r#"<text x="{:.1}" y="{:.1}" text-anchor="end">{}</text>"#,
                LEFT - 6.0,
                gy + 4.0,
                number_label(y)
            );
        }
    }
    let _ = writeln!(
        s,
        r##"<rect x="{LEFT}" y="{TOP}" width="{:.1}" height="{:.1}" fill="none" stroke="#333"/>"##,
        W - LEFT - RIGHT,
        H - TOP - BOTTOM
    );
    let _ = writeln!(
        s,
        r#"<text x="{:.1}" y="{:.1}" text-anchor="middle">fluid particles</text>"#,
        (LEFT + W - RIGHT) / 2.0,
        H - 18.0
    );
    let _ = writeln!(
        s,
        r#"<text transform="translate(22 {:.1}) rotate(-90)" text-anchor="middle">nanoseconds per particle-step</text>"#,
        (TOP + H - BOTTOM) / 2.0
    );
    // Series and legend.
    for (k, ((code, threads), pts)) in series.iter().enumerate() {
        let colour = match (code, threads) {
            (Code::Dfsph2d, 1) => "#1f77b4",
            (Code::Dfsph2d, _) => "#2ca02c",
            (Code::Salva2d, 1) => "#ff7f0e",
            (Code::Salva2d, _) => "#d62728",
        };
        let dash = if *threads == 1 {
            r#" stroke-dasharray="6 3""#
        } else {
            ""
        };
        let path: Vec<String> = pts
            .iter()
            .map(|&(x, y)| format!("{:.1},{:.1}", px(x), py(y)))
            .collect();
        let _ = writeln!(
            s,
            r#"<polyline points="{}" fill="none" stroke="{colour}" stroke-width="2"{dash}/>"#,
            path.join(" ")
        );
        for &(x, y) in pts {
            let _ = writeln!(
                s,
                r#"<circle cx="{:.1}" cy="{:.1}" r="4" fill="{colour}"/>"#,
                px(x),
                py(y)
            );
        }
        let ly = TOP + 10.0 + 22.0 * k as f64;
        let lx = W - RIGHT + 16.0;
        let _ = writeln!(
            s,
            r#"<line x1="{lx}" y1="{ly}" x2="{}" y2="{ly}" stroke="{colour}" stroke-width="2"{dash}/>"#,
            lx + 26.0
        );
        let _ = writeln!(
            s,
            r#"<text x="{}" y="{}">{} ({} thread{})</text>"#,
            lx + 32.0,
            ly + 4.0,
            code.name(),
            threads,
            if *threads == 1 { "" } else { "s" }
        );
    }
    s.push_str("</svg>\n");
    s
}

fn count_label(x: f64) -> String {
    if x >= 1.0e6 {
        format!("{}M", x / 1.0e6)
    } else if x >= 1.0e3 {
        format!("{}k", x / 1.0e3)
    } else {
        format!("{x}")
    }
}

fn number_label(y: f64) -> String {
    if y >= 1.0 {
        format!("{y:.0}")
    } else {
        format!("{y}")
    }
}
