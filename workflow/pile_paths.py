"""Where the files of the piles lie in a configuration's results folder
(config ``results``): state files (docs/formats.md#state-files), logs,
benchmarks, checkpoints, frames, films, VTK files and pictures.
"""

from workflow.stages import stage_rule


class PilePaths:
    """The paths of the piles' files under one results folder.

    Each method also gives the pattern the rules name when called with
    wildcards (``"{protocol}", "{seed}", "{stage}"``).

    Parameters
    ----------
    results : str
        The results folder (config ``results``, relative to the working directory).
    """

    def __init__(self, results):
        #: The folder of everything this configuration makes.
        self.folder = results
        #: Flag file written by rule compile_kernels; every simulation rule
        #: takes it as input so that no two jobs compile (and write the Numba
        #: cache) at once.
        self.compiled_flag = self.results_path(".numba/compiled.ok")
        #: The table of the simulation jobs' run times (rule run_times_table, in the report).
        self.run_times_table = self.results_path("run_times.html")

    def results_path(self, path):
        """`path` (e.g. ``"piles/{protocol}/seed{seed}/poured.nc"``) in the results folder."""
        return f"{self.folder}/{path}"

    def pile(self, protocol, seed, stage):
        """Path of a particle-state file (docs/formats.md#state-files)."""
        return self.results_path(f"piles/{protocol}/seed{seed}/{stage}.nc")

    def _job_file(self, folder, protocol, seed, stage, suffix):
        """Path of a file of the job making `stage` in `folder` (``logs``,
        ``benchmarks``): ``{folder}/{rule}/{protocol}/seed{seed}.{suffix}``
        for a pour or relaxation, ``seed{seed}_{stage}`` for a probe."""
        rule = stage_rule(stage)
        job = f"seed{seed}_{stage}" if rule == "probe" else f"seed{seed}"
        return self.results_path(f"{folder}/{rule}/{protocol}/{job}.{suffix}")

    def stage_log(self, protocol, seed, stage):
        """The log with the progress lines of the job making `stage`
        (study_progress.py reads them): the rule's ``log:`` for a relaxation
        or a probe, the pile's :meth:`pour_log` for ``poured``. With the
        wildcards ``"{protocol}", "{seed}"`` and a stage (or ``"{stage}"``)
        it is the pattern the rules name."""
        return self._job_file("logs", protocol, seed, stage, "log")

    def stage_benchmark(self, protocol, seed, stage):
        """The benchmark file (the rule's ``benchmark:``) of the job making
        `stage`, also as a pattern with wildcards as :meth:`stage_log`."""
        return self._job_file("benchmarks", protocol, seed, stage, "tsv")

    def pour_log(self, protocol, seed):
        """The pile's pour log: the lines of every run of its pour that held the
        pour's lock, each run from a line "pour P seed S: started by process
        HOST PID" (the simulator's --log; study_progress.py reads its progress
        lines). Not the pour rule's ``log:``, which holds what one job printed."""
        return self.stage_log(protocol, seed, "poured")

    def pour_checkpoint(self, protocol, seed):
        """Checkpoint of a running pour. Deliberately not a Snakemake output: it
        must survive a killed job so that the re-run resumes from it; the
        simulator deletes it when the pour has finished."""
        return self.results_path(f"piles/{protocol}/seed{seed}/pour.checkpoint.nc")

    def pour_finished(self, protocol, seed):
        """Copy of a finished pour (python -m sim pour --finished; its frames
        beside it, ``pour.finished.frames.nc``). Deliberately not a Snakemake
        output: Snakemake, interrupted while a pour ran, marks the outputs of
        the pour that then finishes incomplete, and its rerun deletes them and
        runs the pour again, which takes this copy instead of pouring. Superseded
        by each pour that finishes, removed by one under other settings or code."""
        return self.results_path(f"piles/{protocol}/seed{seed}/pour.finished.nc")

    def pile_frames(self, protocol, seed):
        """Path of the frames of a pile's pour (python -m sim pour --frames; output film)."""
        return self.results_path(f"piles/{protocol}/seed{seed}/frames.nc")

    def pile_film(self, protocol, seed, ext="mp4"):
        """Path of the film of a pile's pour (python -m analysis film): the MP4,
        or with ext="html" the page holding it that the report shows."""
        return self.results_path(f"films/{protocol}_seed{seed}.{ext}")

    def pile_vtk(self, protocol, seed, stage):
        """Path of the VTK file of one pile state's particles (python -m analysis
        export; its contact network is the same name with _contacts)."""
        return self.results_path(f"vtk/{protocol}_seed{seed}_{stage}.vtu")

    def pile_figure(self, protocol, seed, stage):
        """Path of the picture of one pile state."""
        return self.results_path(f"figures/piles/{protocol}_seed{seed}_{stage}.png")

