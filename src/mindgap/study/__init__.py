"""The study app: run the dissertation's user studies with real people in a browser.

Study files (:mod:`.config`), the items they show (:mod:`.items`), the SQLite store
(:mod:`.store`), the web app (:mod:`.app`), exports to the files the fitting commands
read (:mod:`.export`, :mod:`.prefs_file`), fitting a reward from recorded preferences
(:mod:`.offline`) and the live teacher a training run asks (:mod:`.live`). The web
stack (FastAPI, uvicorn, Jinja2) is the ``study`` extra: ``pip install mindgap[study]``.
"""

from .config import Study as Study
from .config import StudyFileError as StudyFileError
from .config import load_study as load_study
from .prefs_file import Preferences as Preferences
from .prefs_file import PreferencesFileError as PreferencesFileError
from .prefs_file import read_preferences as read_preferences
from .store import Store as Store
from .store import StoreError as StoreError
