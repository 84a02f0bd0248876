//! Files the viewer writes: particle CSV, PNG screenshots, and the session record.

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use dfsph::Snapshot;
use eframe::egui::ColorImage;

/// Write `x,y,vx,vy,density,pressure` (m, m/s, kg/m³, Pa), one row per particle in id order:
/// the CSV of `dfsph2d run` ([`dfsph_io::csv::write_snapshot_csv`]), written atomically.
pub fn write_particles_csv(path: &Path, snap: &Snapshot) -> anyhow::Result<()> {
    dfsph_io::csv::write_snapshot_csv(path, snap)
}

/// Save a screenshot as an RGBA PNG.
pub fn save_png(path: &Path, image: &ColorImage) -> anyhow::Result<()> {
    let [w, h] = image.size;
    let rgba: Vec<u8> = image
        .pixels
        .iter()
        .flat_map(|c| c.to_srgba_unmultiplied())
        .collect();
    image::save_buffer(path, &rgba, w as u32, h as u32, image::ColorType::Rgba8)
        .with_context(|| format!("saving {}", path.display()))
}

/// Read a PNG as `(width, height, RGBA pixels)`; for tests that check screenshots.
pub fn read_png(path: &Path) -> anyhow::Result<(u32, u32, Vec<[u8; 4]>)> {
    let img = image::open(path)
        .with_context(|| format!("reading {}", path.display()))?
        .to_rgba8();
    let (w, h) = img.dimensions();
    Ok((w, h, img.pixels().map(|p| p.0).collect()))
}

/// `dfsph2d-YYYYMMDD-HHMMSS.png` (UTC) in `dir`, with `-2`, `-3`, ... appended when taken.
pub fn timestamped_png(dir: &Path) -> PathBuf {
    crate::file_names::timestamped_file(dir, "png")
}

/// The browser's screenshot: the simulation drawn by `dfsph2d run`'s CPU rasteriser in the
/// viewer's colouring (`field`) and look (`look`), with its
/// time stamped, downloaded as `dfsph2d-YYYYMMDD-HHMMSS.png`. Returns the name.
#[cfg(target_arch = "wasm32")]
pub fn download_rendered_png(
    sim: &dfsph::Simulation,
    field: dfsph_io::render::FrameField,
    look: dfsph_io::render::WaterLook,
) -> anyhow::Result<String> {
    use dfsph_io::render::{render_frame, stamp_time, RenderGeometry, RenderOptions};
    let options = RenderOptions {
        width: crate::video::FRAME_WIDTH,
        field,
        scale_max: dfsph_io::render::field_scale(sim.scene(), field),
        look,
    };
    let mut picture = render_frame(&RenderGeometry::of(sim), &sim.snapshot(), &options)?;
    stamp_time(&mut picture, sim.time(), 2);
    let png = picture
        .encode_png()
        .map_err(|e| anyhow::anyhow!("cannot encode the PNG: {e}"))?;
    let name = format!("dfsph2d-{}.png", crate::file_names::utc_stamp_now());
    crate::web::download(&name, "image/png", &png)
        .map_err(|e| anyhow::anyhow!("the browser refused the download: {e}"))?;
    Ok(name)
}

#[cfg(test)]
mod tests {
    use super::*;
    use dfsph::Vec2;
    use eframe::egui::Color32;

    #[test]
    fn csv_and_png_round_trip() {
        let dir = std::env::temp_dir().join(format!("dfsph-viewer-export-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let snap = Snapshot {
            time: 1.0,
            id: vec![0, 1],
            position: vec![Vec2::new(0.5, 0.25), Vec2::new(1.0, 2.0)],
            velocity: vec![Vec2::new(-1.0, 0.0), Vec2::ZERO],
            density: vec![1000.0, 999.5],
            pressure: vec![10.0, 0.0],
        };
        let csv = dir.join("particles.csv");
        write_particles_csv(&csv, &snap).unwrap();
        let text = std::fs::read_to_string(&csv).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], "x,y,vx,vy,density,pressure");
        assert_eq!(lines[1], "0.5,0.25,-1,0,1000,10");
        assert_eq!(lines.len(), 3);

        let mut img = ColorImage::filled([3, 2], Color32::BLACK);
        img.pixels[4] = Color32::from_rgb(10, 200, 30);
        let png = timestamped_png(&dir);
        assert!(png
            .file_name()
            .unwrap()
            .to_str()
            .unwrap()
            .starts_with("dfsph2d-"));
        save_png(&png, &img).unwrap();
        let (w, h, px) = read_png(&png).unwrap();
        assert_eq!((w, h), (3, 2));
        assert_eq!(px[4], [10, 200, 30, 255]);
        assert_ne!(timestamped_png(&dir), png);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
