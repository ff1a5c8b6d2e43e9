#!/usr/bin/env python3
"""The doc runner on pages written here: what matches, what fails and how the failure reads, what is skipped."""

import os
import subprocess
import sys
import tempfile
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import doc_runner  # noqa: E402


def run_page(text, shared=None):
    """Runs a page in a scratch repository; returns (exit status, output)."""
    with tempfile.TemporaryDirectory() as repo:
        os.makedirs(os.path.join(repo, "build", "bin"))
        os.makedirs(os.path.join(repo, "logs"))
        with open(os.path.join(repo, "logs", "a.txt"), "w") as f:
            f.write("from the repository\n")
        with open(os.path.join(repo, "page.md"), "w") as f:
            f.write(text)
        args = [sys.executable, os.path.join(HERE, "doc_runner.py"), os.path.join(repo, "page.md"), "--repo", repo,
                "--bin", os.path.join(repo, "build", "bin"), "--work", os.path.join(repo, "build", "work", "page")]
        if shared:
            args += ["--shared", shared]
        p = subprocess.run(args, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        return p.returncode, p.stdout


class Matching(unittest.TestCase):
    def test_numbers_within_the_last_digit_or_the_stated_tolerance(self):
        m = doc_runner.matches
        self.assertTrue(m(["ATE 0.048 m"], ["ATE 0.049 m"], None))
        self.assertFalse(m(["ATE 0.048 m"], ["ATE 0.050 m"], None))
        self.assertFalse(m(["407 loops"], ["408 loops"], None))
        self.assertTrue(m(["407 loops"], ["409 loops"], (0.01, True)))
        self.assertTrue(m(["0.500 s"], ["0.530 s"], (0.05, False)))
        self.assertTrue(m(["67,462 events"], ["67,462 events"], None))
        self.assertFalse(m(["-15.0 ms"], ["15.0 ms"], None))
        self.assertFalse(m(["15 ms"], ["15.0 ms"], None))

    def test_words_and_spacing(self):
        m = doc_runner.matches
        self.assertTrue(m(["IMU    fault   24001"], ["IMU fault      24001"], None))
        self.assertFalse(m(["p99 18.9 ms"], ["p50 18.9 ms"], None))
        self.assertTrue(m(["2025-11-22 02:00:00.000000 UTC"], ["2025-11-22 02:00:00.000000 UTC"], None))

    def test_elisions(self):
        m = doc_runner.matches
        self.assertTrue(m(["a", "...", "b"], ["a", "x", "y", "b"], None))
        self.assertTrue(m(["a", "...", "b"], ["a", "b"], None))
        self.assertFalse(m(["a", "b"], ["a", "x", "b"], None))
        self.assertTrue(m(["in ... s (...x real time): 5 events"], ["in 19.91 s (135x real time): 5 events"], None))
        self.assertFalse(m(["in ... s: 5 events"], ["in 19.91 s: 6 events"], None))


class Pages(unittest.TestCase):
    def test_a_page_that_matches(self):
        status, out = run_page("""Text.

```console
$ echo 'ATE 0.0481 m' && echo "took $RANDOM ms"
ATE 0.048 m
took ... ms
$ for i in 1 2; do
>   echo $i
> done
1
2
$ cat > x.yaml <<EOF
a: 1
EOF
$ cat x.yaml logs/a.txt
a: 1
from the repository
```

<!-- doc-test: tolerance 1% -->
```console
$ echo 'loops 409'
loops 407
```
""")
        self.assertEqual(status, 0, out)
        self.assertIn("5 commands run, 0 blocks skipped, 0 failed", out)

    def test_a_failure_names_the_page_line_and_command_with_a_diff(self):
        status, out = run_page("""# Page

```console
$ echo 'ATE 0.052 m'
ATE 0.048 m
```
""")
        self.assertEqual(status, 1, out)
        self.assertIn("page.md:4: FAILED", out)
        self.assertIn("$ echo 'ATE 0.052 m'", out)
        self.assertIn("-ATE 0.048 m", out)
        self.assertIn("+ATE 0.052 m", out)

    def test_the_exit_status_counts(self):
        status, out = run_page("```console\n$ false\n```\n")
        self.assertEqual(status, 1, out)
        self.assertIn("exit status 1, expected 0", out)
        status, out = run_page("<!-- doc-test: exit 3 -->\n```console\n$ exit 3\n```\n")
        self.assertEqual(status, 0, out)

    def test_skipped_blocks_say_why_and_output_alone_must_be_marked(self):
        status, out = run_page("<!-- doc-test: skip needs a live bus -->\n```console\n$ sleep 1000\n```\n")
        self.assertEqual(status, 0, out)
        self.assertIn("page.md:2: skipped: needs a live bus", out)
        status, out = run_page("```console\nsome output\n```\n")
        self.assertNotEqual(status, 0, out)
        self.assertIn("mark it <!-- doc-test: skip REASON -->", out)

    def test_without_shared_data_a_page_that_reads_it_is_skipped(self):
        status, out = run_page("```console\n$ ls ../shared/data\n```\n", shared="/nonexistent/shared/data")
        self.assertEqual(status, 77, out)

    def test_shared_data_is_beside_the_work_folder(self):
        with tempfile.TemporaryDirectory() as top:
            data = os.path.join(top, "shared", "data")
            os.makedirs(data)
            open(os.path.join(data, "x.bag"), "w").close()
            status, out = run_page("```console\n$ ls ../shared/data\nx.bag\n```\n", shared=data)
            self.assertEqual(status, 0, out)


if __name__ == "__main__":
    unittest.main()
