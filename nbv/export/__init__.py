"""Export evaluation runs and datasets to PC-NBV's file layout, to cross-check coverage and AUC."""
