//! SVG to pixels, without a window, GPU or system font: resvg (on tiny-skia) with egui's bundled Ubuntu
//! font. The experiment figures (plotters draws SVG) and the headless animations (each frame an SVG) both
//! go through here.

use resvg::tiny_skia::Pixmap;
use resvg::usvg;
use std::sync::Arc;

/// Parse options with the bundled font as every family: build once, reuse for every frame.
pub(crate) fn options() -> usvg::Options<'static> {
    let mut options = usvg::Options::default();
    let fonts = Arc::make_mut(&mut options.fontdb);
    fonts.load_font_data(epaint_default_fonts::UBUNTU_LIGHT.to_vec());
    let family = fonts.faces().next().and_then(|f| f.families.first()).map(|f| f.0.clone());
    if let Some(family) = family {
        fonts.set_sans_serif_family(family.clone());
        options.font_family = family;
    }
    options
}

/// Rasterizes SVG text at its own size.
pub(crate) fn rasterize(svg: &str, options: &usvg::Options) -> crate::error::Result<Pixmap> {
    let draw_err = |e: &dyn std::fmt::Display| format!("cannot draw: {e}");
    let tree = usvg::Tree::from_str(svg, options).map_err(|e| draw_err(&e))?;
    let size = tree.size().to_int_size();
    let mut pixmap = Pixmap::new(size.width(), size.height()).ok_or("cannot draw: empty image")?;
    resvg::render(&tree, resvg::tiny_skia::Transform::default(), &mut pixmap.as_mut());
    Ok(pixmap)
}
