"""Design-stage reliability of planned blocks: design blocks, Gruen's point classes and
reliability tables, advice, Gruen's and FOTEF's studies, modified snooping of a block.
"""
