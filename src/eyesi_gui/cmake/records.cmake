# Placeholder until the records store lands (helper).
