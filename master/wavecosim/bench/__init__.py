"""`wavecosim bench`: the cost of the inner iteration and of whole runs, side by side with their floors."""
