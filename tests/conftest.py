import sys
from pathlib import Path

# tests/thesis_oracle.py and other test helpers import as top-level modules
sys.path.insert(0, str(Path(__file__).resolve().parent))
