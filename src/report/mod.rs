//! Reports: SVG charts and the HTML index.
pub mod compact;
pub mod html;
pub mod ledger;
pub mod legend;
pub mod measured;
pub mod plot;
pub mod snapshot;
