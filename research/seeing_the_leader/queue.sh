#!/bin/sh
# Run perception variants one after another (a variant whose result is cached is skipped):
#   PYTHON=/path/to/python sh research/seeing_the_leader/queue.sh SEED VARIANT...
# The package must be importable (PYTHONPATH set to the checkout).
cd "$(dirname "$0")" || exit 1
seed=$1
shift
for v in "$@"; do
    nice -n 10 "${PYTHON:-python}" perception.py --variant "$v" --seed "$seed" \
        || echo "variant $v failed"
done
