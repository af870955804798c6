"""End-to-end tier: whole scans of small scenes, checked against exact ground truth."""

import pytest

pytest.importorskip("bpy", reason="the e2e tier needs bpy (installed by the README's set-up)")
