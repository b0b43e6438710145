"""What people look at: figures (:mod:`.plots`), the report files of a run (:mod:`.reports`) and a live rerun view
(:mod:`.viewer`). Results never draw themselves: this layer draws them, and nothing below imports it.
"""
