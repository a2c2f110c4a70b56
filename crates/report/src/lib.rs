//! `report`: the figures and the self-contained HTML report of the IPA identification study.
//!
//! - [`plot`]: figures ([`Figure`] of stacked [`Panel`]s of [`Series`]) rendered as SVG and PNG with an
//!   embedded font, so that rendering needs no system font.
//! - [`html`]: a small builder for a single-file HTML report (sections, escaped text, tables with the
//!   paper's values beside ours, figures inline), readable in print and without JavaScript.
//!
//! - [`format`]: numbers as reports print them.
//!
//! It depends on no estimator, plant or controller: the reproduction pipeline (crate `ipa-reproduce`)
//! and the command line feed it plain numbers.

pub mod error;
pub mod format;
pub mod html;
pub mod plot;

pub use error::ReportError;
pub use html::Report;
pub use plot::{render_png, render_svg, save_figure, Figure, Panel, Series, SeriesStyle};

/// The examples of `docs/report.md`, compiled and run as doctests so that the guide stays true.
#[cfg(doctest)]
#[doc = include_str!("../../../docs/report.md")]
struct ReportGuideDoctests;
