//! One module per `sdctl` command: its clap arguments and its body.

pub(crate) mod alias;
pub(crate) mod analyze;
pub(crate) mod analyze_measured;
pub(crate) mod bode;
pub(crate) mod c2d;
pub(crate) mod connect;
pub(crate) mod d2c;
pub(crate) mod diagnose;
pub(crate) mod downsample;
pub(crate) mod fit;
pub(crate) mod fit_stabilization;
pub(crate) mod freqresp;
pub(crate) mod frf;
pub(crate) mod h2syn;
pub(crate) mod hinfsyn;
pub(crate) mod intersample;
pub(crate) mod loopshape;
pub(crate) mod mixsyn;
pub(crate) mod multisine;
pub(crate) mod norm;
pub(crate) mod predict;
pub(crate) mod reduce;
pub(crate) mod roots;
pub(crate) mod testbed;
pub(crate) mod uncertainty;
pub(crate) mod weight;
