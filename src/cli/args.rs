//! The value types of the command line's options (profiles, DAG formats, export engines,
//! bench engines and cases).

use clap::ValueEnum;

/// Profiles.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq)]
pub enum ProfileArg {
    /// Minutes on 2 cores (CI, golden snapshots).
    Quick,
    /// The chapter's resolution.
    Paper,
}

impl ProfileArg {
    /// The profile's name in `pipeline.yaml`.
    pub fn name(self) -> &'static str {
        match self {
            ProfileArg::Quick => "quick",
            ProfileArg::Paper => "paper",
        }
    }
}

/// DAG output formats.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq)]
pub enum DagFormat {
    /// Graphviz DOT.
    Dot,
    /// Mermaid flowchart.
    Mermaid,
}

/// Workflow engines `export` writes for.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq)]
pub enum ExportEngine {
    /// A Snakefile: one rule per stage (`snakemake -j N`, `--executor slurm`).
    Snakemake,
}

/// Benchmarked engines.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq)]
pub enum BenchEngine {
    /// ~3000-grain a = 1 DEM column, table 4.2 parameters.
    Dem,
    /// 40,000-point a = 1 MPM column, 16 PPC, 2 mm cells, Mohr–Coulomb.
    Mpm,
    /// CD deposit of the Siconos reference script (25 × 20 and 40 × 25 disks, h = 2e-3 s).
    Cd,
    /// CD on dense packings: the 40 × 25 deposit settled (untimed), timed at rest and kicked
    /// with the pile's gradient excitation at 13 mgd (`--scene-out DIR` writes both scenes as
    /// CSV for `bench/siconos/dense.py`).
    CdDense,
    /// Cost growth: wall time per step against grain / point count (1e3 … 1e5; the DEM to
    /// 1e6 with `--max-n 1000000`) for DEM, CD and MPM, one thread, the DEM's grains
    /// shuffled (`--lattice-order`: as built); a table, JSON lines and `--svg FILE`.
    Scaling,
    /// In-step parallelism crossover: DEM step time on 1 thread and on every thread of the
    /// machine (thread team forced on) for the settled column cut to 250 … 5848 grains.
    DemCrossover,
    /// Per-stage table of the optional terms and outputs each scene enables, and the step
    /// cost of its configuration against everything on (issue 12; docs/stability.md).
    LeaveOut,
}

/// DEM benchmark physics.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq)]
pub enum BenchCaseArg {
    /// Table 4.2: rolling resistance with the implicit dashpot, energy ledger.
    Full,
    /// Rolling resistance, no ledger.
    RollingNoLedger,
    /// LAMMPS `gran/hooke/history` physics: no rolling resistance, no ledger.
    NoRolling,
}
