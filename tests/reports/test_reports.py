"""The reports package on the committed results fixtures (tests/fixtures/results/): each fixture
matches its schema (reports/schema/), every report kind renders from it with the stored numbers
formatted as the reports promise (relative errors 100 x with 2 decimals, forces in mN with 4),
the plots are written, and a missing results.json or matplotlib ends with status 2 naming it.

    /usr/bin/python3 tests/reports/test_reports.py [SOURCE_DIR]
"""
import json
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile
import unittest

SOURCE = pathlib.Path(os.environ.get("TOUCHSTONE_SOURCE_DIR") or pathlib.Path(__file__).resolve().parents[2])
FIXTURES = SOURCE / "tests" / "fixtures" / "results"
SCHEMAS = SOURCE / "reports" / "schema"
PACKAGE_DIR = SOURCE / "reports"


def load(name):
    with open(FIXTURES / name, encoding="utf-8") as f:
        return json.load(f)


def run_report(kind, out, *arguments, pythonpath=None):
    """`python3 -m touchstone_reports KIND OUT ...` as the C++ launcher runs it."""
    env = dict(os.environ, PYTHONPATH=pythonpath or str(PACKAGE_DIR))
    return subprocess.run([sys.executable, "-m", "touchstone_reports", kind, str(out), *arguments],
                           env=env, capture_output=True, text=True, timeout=300)


def output_with(fixture, name="results.json"):
    """A temporary output folder holding the fixture as `name`."""
    out = pathlib.Path(tempfile.mkdtemp(prefix="touchstone_reports_test_"))
    shutil.copy(FIXTURES / fixture, out / name)
    return out


def percent(x, digits=2):
    """The reports' contract for a relative value: 100 x with `digits` decimals, "n/a" for null."""
    return "n/a" if x is None else "%.*f %%" % (digits, 100 * x)


def row_cells(markdown, prefix, count=None):
    """The cells of the first table row starting with `prefix` (outer pipes stripped), of
    `count` cells when given (tables of one report can share a row's first cells)."""
    for line in markdown.splitlines():
        if line.startswith(prefix):
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            if count is None or len(cells) == count:
                return cells
    raise AssertionError("no row starting with %r%s" % (prefix, "" if count is None else " of %d cells" % count))


class Schemas(unittest.TestCase):
    def test_fixtures_match_their_schemas(self):
        import jsonschema

        for fixture, schema in (("study_results.json", "study_results.schema.json"),
                                ("collision_results.json", "collision_results.schema.json")):
            with self.subTest(fixture=fixture):
                with open(SCHEMAS / schema, encoding="utf-8") as f:
                    schema_doc = json.load(f)
                jsonschema.Draft202012Validator.check_schema(schema_doc)
                jsonschema.Draft202012Validator(schema_doc).validate(load(fixture))

    def test_schema_rejects_a_case_without_its_errors(self):
        import jsonschema

        with open(SCHEMAS / "study_results.schema.json", encoding="utf-8") as f:
            schema_doc = json.load(f)
        results = load("study_results.json")
        mfs = next(c for c in results["cases"] if c["model"] == "mfs")
        del mfs["error"]["force_rel"]
        with self.assertRaises(jsonschema.ValidationError):
            jsonschema.Draft202012Validator(schema_doc).validate(results)


class StudyReport(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.results = load("study_results.json")
        cls.out = output_with("study_results.json")
        cls.process = run_report("study", cls.out)
        cls.md = (cls.out / "report.md").read_text(encoding="utf-8") if cls.process.returncode == 0 else ""

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.out, ignore_errors=True)

    def test_written(self):
        self.assertEqual(self.process.returncode, 0, self.process.stderr)
        self.assertIn("report: %s" % (self.out / "report.md"), self.process.stdout)
        self.assertFalse((self.out / "report.md.partial").exists())

    def test_plots_exist(self):
        for plot in ("force_depth", "force_error_vs_n", "pareto", "displacement_axis"):
            path = self.out / "plots" / (plot + ".png")
            self.assertTrue(path.is_file(), path)
            self.assertGreater(path.stat().st_size, 1000, path)
            self.assertIn("(plots/%s.png)" % plot, self.md)

    def test_mfs_rows_show_the_stored_errors(self):
        mfs = [c for c in self.results["cases"] if c["model"] == "mfs"]
        self.assertGreater(len(mfs), 0)
        for c in mfs:
            cells = row_cells(self.md, "| `%s` | %s" % (c["id"], c["params"]["formulation"]))
            e = c["error"]
            # Columns: case, formulation, N, F [mN], force error, signed, ref. error, displacement error, ...
            self.assertEqual(cells[2], str(c["params"]["node_count"]))
            self.assertEqual(cells[3], "%.4f" % (1e3 * c["qoi"]["axial_force_N"]))
            self.assertEqual(cells[4], "%.2f %%" % (100 * e["force_rel"]))
            self.assertEqual(cells[5], "%.2f %%" % (100 * e["force_signed_rel"]))
            self.assertEqual(cells[6], "±" + percent(e["reference_uncertainty_rel"], 3))
            self.assertEqual(cells[7], "%.2f %%" % (100 * e["disp_rel_l2"]))
            self.assertEqual(cells[8], "%.2f" % (1e6 * e["disp_max_m"]))

    def test_reference_line(self):
        ref = self.results["reference_summary"]
        self.assertIn("**Reference**: `%s` = %.4f mN at δ = %g mm; estimated discretisation error **%s**" % (
            ref["case"], 1e3 * ref["axial_force_N"], 1e3 * self.results["depths_m"][-1], percent(ref["uncertainty_rel"], 3)),
            self.md)
        self.assertIn("Displacement reference: `%s`, estimated error %s" % (
            ref["probes_from"], percent(ref["disp_uncertainty_rel"])), self.md)

    def test_targets_counted(self):
        targets = self.results["targets"]
        met = sum(1 for t in targets if t.get("met") is True)
        missed = sum(1 for t in targets if t.get("met") is False)
        self.assertIn("%d met, **%d missed**, %d not measured by this study." % (met, missed, len(targets) - met - missed),
                      self.md)


class CollisionReport(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.results = load("collision_results.json")
        cls.out = output_with("collision_results.json")
        cls.process = run_report("collision", cls.out)
        cls.md = (cls.out / "report.md").read_text(encoding="utf-8") if cls.process.returncode == 0 else ""

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.out, ignore_errors=True)

    def test_written_with_plots(self):
        self.assertEqual(self.process.returncode, 0, self.process.stderr)
        for plot in ("table1_overlap_tests.png", "tremor_error.png", "cycle_cost.png"):
            self.assertTrue((self.out / plot).is_file(), plot)
            self.assertIn("](%s)" % plot, self.md)
        self.assertNotIn("No plots", self.md)

    def test_every_tree_row(self):
        for r in self.results["table1"]:
            cells = row_cells(self.md, "| %s | %s | %s |" % (r["organ"], r["tree"], r["bounding_volume"]))
            self.assertEqual(len(cells), 10, r["id"])
            self.assertEqual(cells[3], str(r["depth"]))
            self.assertEqual(cells[5], "%.1f / %.0f" % (r["box_tests"]["mean"], r["box_tests"]["max"]))
            self.assertEqual(cells[8], "%.0f" % r["query_time_ns"])
            self.assertEqual(cells[9], "%.1f" % r["build_ms"])

    def test_replica_row(self):
        binary = [r for r in self.results["table1"] if r["tree"] == "binary" and r["bounding_volume"] == "obb"]
        self.assertGreater(len(binary), 0)
        for r in binary:
            cells = row_cells(self.md, "| %s | %d | " % (r["organ"], r["triangles"]), 12)
            self.assertEqual(len(cells), 12)
            self.assertEqual(cells[2], str(r["binary_depth"]))
            self.assertEqual(cells[3], str(r["binary_depth"] - 1))
            self.assertEqual(cells[4], "–" if r["paper_overlap_tests"] is None else str(r["paper_overlap_tests"]))
            self.assertEqual(cells[5], "%.1f / %.0f" % (r["nodes_entered"]["mean"], r["nodes_entered"]["max"]))

    def test_tremor_rows(self):
        for r in self.results["tremor"]:
            cells = row_cells(self.md, "| %.2f | %d | %.0f |" % (1e3 * r["amplitude_m"], r["window_samples"],
                                                                  r["sample_rate_hz"]))
            median = r["error_m"]["median"]
            self.assertEqual(cells[4], "miss" if median is None else "%.3f" % (1e3 * median))
            self.assertEqual(cells[7], str(r["no_hit"]))

    def test_settings_quoted(self):
        s = self.results["settings"]
        self.assertIn("%d approach trajectories per organ (tremor %.2f mm RMS per axis)" % (
            s["trajectories"], 1e3 * s["approach_tremor_rms_per_axis_m"]), self.md)
        self.assertIn("straight-line range %.1f mm" % (1e3 * s["prediction"]["straight_line_range_m"]), self.md)

    def test_without_plots_says_why(self):
        out = output_with("collision_results.json")
        try:
            run = run_report("collision", out, "--no-plots")
            self.assertEqual(run.returncode, 0, run.stderr)
            md = (out / "report.md").read_text(encoding="utf-8")
            self.assertIn("(No plots: not asked for.)", md)
            self.assertNotIn(".png)", md)
            self.assertEqual(sorted(p.name for p in out.iterdir()), ["report.md", "results.json"])
        finally:
            shutil.rmtree(out, ignore_errors=True)


class ShortReports(unittest.TestCase):
    def render(self, kind, fixture, name="results.json"):
        out = output_with(fixture, name)
        self.addCleanup(shutil.rmtree, out, True)
        run = run_report(kind, out)
        self.assertEqual(run.returncode, 0, run.stderr)
        return (out / "report.md").read_text(encoding="utf-8")

    def test_fem(self):
        results = load("fem_results.json")
        md = self.render("fem", "fem_results.json")
        for c in results["cases"]:
            cells = row_cells(md, "| `%s` |" % c["id"])
            self.assertEqual(cells[3], "%.4f" % (1e3 * c["qoi"]["axial_force_N"]))
            if c["error"]["force_rel"] is not None:
                self.assertEqual(cells[5], "%.2f %%" % (100 * c["error"]["force_rel"]))

    def test_mfs(self):
        results = load("mfs_results.json")
        md = self.render("mfs", "mfs_results.json")
        for c in results["cases"]:
            cells = row_cells(md, "| `%s` |" % c["id"])
            self.assertEqual(cells[1], str(c["params"]["node_count"]))
            self.assertEqual(cells[2], "%.4f" % (1e3 * c["qoi"]["axial_force_N"]))
            self.assertEqual(cells[6], c["status"])
            self.assertEqual(cells[7], ", ".join(c["accuracy"]["flags"]) or "-")

    def test_sim(self):
        summary = load("sim_summary.json")
        md = self.render("sim", "sim_summary.json", "summary.json")
        haptic = summary["loops"]["haptic"]
        cells = row_cells(md, "| haptic |")
        self.assertEqual(cells[1], str(haptic["ticks"]))
        self.assertEqual(cells[2], "%.1f µs" % (1e6 * haptic["lateness_p99_s"]))
        self.assertIn("Largest force %.4g N" % summary["forces"]["max_force_N"], md)


    def test_replay(self):
        results = load("replay_results.json")
        md = self.render("replay", "replay_results.json")
        self.assertIn("| force error, RMS over the contacts of each contact's relative L2 | %.2f %% |"
                      % (100 * results["summary"]["force_error_rms_over_contacts"]), md)
        for c in results["contacts"]:
            cells = row_cells(md, "| %s | %s |" % (c["label"], c["reason"]))
            self.assertEqual(cells[5], "%.4f" % c["axial_stiffness_mfs_N_per_m"])
            self.assertEqual(cells[6], "%.4f" % c["axial_stiffness_reference_N_per_m"])
            self.assertEqual(cells[7], "%.2f %%" % (100 * c["stiffness_error"]))
            self.assertEqual(cells[9], "%.3f %%" % (100 * c["reference_convergence"]["relative_uncertainty"]))
        self.assertIn("![force over time](force_over_time.png)", md)


class Failures(unittest.TestCase):
    def test_missing_results_exit_2_naming_the_file(self):
        out = pathlib.Path(tempfile.mkdtemp(prefix="touchstone_reports_test_"))
        self.addCleanup(shutil.rmtree, out, True)
        for kind, name in (("study", "results.json"), ("collision", "results.json"), ("fem", "results.json"),
                           ("mfs", "results.json"), ("sim", "summary.json"), ("replay", "results.json")):
            with self.subTest(kind=kind):
                run = run_report(kind, out)
                self.assertEqual(run.returncode, 2, run.stderr)
                self.assertIn(str(out / name), run.stderr)
                self.assertIn("missing", run.stderr)
                self.assertFalse((out / "report.md").exists())

    def test_unreadable_results_exit_2(self):
        out = pathlib.Path(tempfile.mkdtemp(prefix="touchstone_reports_test_"))
        self.addCleanup(shutil.rmtree, out, True)
        (out / "results.json").write_text("{ not json", encoding="utf-8")
        run = run_report("study", out)
        self.assertEqual(run.returncode, 2)
        self.assertIn(str(out / "results.json") + " is unreadable", run.stderr)

    def test_missing_matplotlib_exit_2(self):
        # A matplotlib that fails to import, first on the path.
        fake = pathlib.Path(tempfile.mkdtemp(prefix="touchstone_reports_test_"))
        self.addCleanup(shutil.rmtree, fake, True)
        (fake / "matplotlib").mkdir()
        (fake / "matplotlib" / "__init__.py").write_text("raise ImportError('no matplotlib here')\n")
        for kind, fixture in (("study", "study_results.json"), ("collision", "collision_results.json")):
            with self.subTest(kind=kind):
                out = output_with(fixture)
                self.addCleanup(shutil.rmtree, out, True)
                run = run_report(kind, out, pythonpath="%s:%s" % (fake, PACKAGE_DIR))
                self.assertEqual(run.returncode, 2, run.stderr)
                self.assertIn("matplotlib is missing", run.stderr)
                self.assertFalse((out / "report.md").exists())


if __name__ == "__main__":
    if len(sys.argv) > 1 and not sys.argv[1].startswith("-"):
        SOURCE = pathlib.Path(sys.argv.pop(1))
        FIXTURES = SOURCE / "tests" / "fixtures" / "results"
        SCHEMAS = SOURCE / "reports" / "schema"
        PACKAGE_DIR = SOURCE / "reports"
    unittest.main(verbosity=2)
