"""Everything baarda writes (result folders, projects, other programs' files, screening
logs, planning files) and the reader of a result folder that the report uses.
"""
