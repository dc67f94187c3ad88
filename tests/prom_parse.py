#!/usr/bin/env python3
"""prom_parse.py - parse a /metrics dump with the Prometheus project's own
Python parser (prometheus_client); exit 1 with the error if it fails.
Used by tests/test_http.c when python3-prometheus-client is installed."""
import sys
from prometheus_client.parser import text_string_to_metric_families

try:
    families = list(text_string_to_metric_families(open(sys.argv[1]).read()))
except Exception as e:  # the parser raises ValueError and friends
    print("parse error:", e)
    sys.exit(1)
print(len(families), "families")
sys.exit(0 if families else 1)
