#!/usr/bin/env bash
# Gradescope's image setup: Python 3.11+ and beacon-sim (from PyPI, or a wheel you put in
# the autograder zip beside this file).
set -euo pipefail
apt-get install -y python3 python3-pip
pip3 install beacon-sim
